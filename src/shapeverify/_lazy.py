"""Names whose module is imported on first use, not when the module naming them is imported.

``from shapeverify._lazy import cKDTree`` in place of ``from scipy.spatial import cKDTree``:
``scipy.spatial`` costs 0.2-0.3 s of CPU to import (sparse matrices, Qhull, the array-API
layer), and most commands never build a k-d tree (an inspection against a prepared model does
not), so the command line should not pay for it at start (issue 32 item 7).
"""

from __future__ import annotations

__all__ = ["cKDTree"]


def cKDTree(*args, **kwargs):  # noqa: N802 - the name of the class it stands for
    """``scipy.spatial.cKDTree(*args, **kwargs)``, importing ``scipy.spatial`` on first use."""
    from scipy.spatial import cKDTree as _cKDTree

    return _cKDTree(*args, **kwargs)
