"""One meaning of ``rng`` everywhere (issue 31: one name per concept).

Every function of shapeverify that takes ``rng`` accepts ``None``, an ``int`` seed or a
:class:`numpy.random.Generator`, and ``rng=None`` always means the fixed seed
:data:`DEFAULT_SEED` (0): deterministic by default, so the same call gives the same answer
(registration, sampling, the simulated scanner, the reports' subsampling alike).  A caller who
wants fresh randomness passes ``np.random.default_rng()``.

>>> import numpy as np
>>> float(generator(None).random()) == float(generator(0).random())
True
>>> g = np.random.default_rng(5)
>>> generator(g) is g
True
"""

from __future__ import annotations

import numpy as np

__all__ = ["generator", "DEFAULT_SEED"]

#: the seed that ``rng=None`` stands for
DEFAULT_SEED = 0


def generator(rng=None) -> np.random.Generator:
    """The :class:`numpy.random.Generator` for ``rng``: ``None`` -> seed :data:`DEFAULT_SEED`,
    an int -> that seed, a Generator -> itself (its stream goes on)."""
    return np.random.default_rng(DEFAULT_SEED if rng is None else rng)
