"""Old keyword names that still work once, with a :class:`DeprecationWarning` (issue 31: one
name per concept).

>>> @renamed_keywords(tolerance="rtol")
... def f(x, rtol=1.0):
...     return rtol
>>> import warnings
>>> with warnings.catch_warnings(record=True) as w:
...     warnings.simplefilter("always")
...     f(1, tolerance=0.5), str(w[0].message)
(0.5, 'f(tolerance=) is now called rtol= (the old name will go)')
"""

from __future__ import annotations

import functools
import warnings

__all__ = ["renamed_keywords"]


def renamed_keywords(**old_to_new):
    """Decorator: accept each old keyword name for its new one, with a
    :class:`DeprecationWarning` at the caller's line; both given: TypeError."""

    def wrap(fn):
        @functools.wraps(fn)
        def inner(*args, **kwargs):
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"{fn.__name__}(): give {new}= only ({old}= is its old "
                                        "name)")
                    warnings.warn(f"{fn.__name__}({old}=) is now called {new}= (the old name "
                                  "will go)", DeprecationWarning, stacklevel=2)
                    kwargs[new] = kwargs.pop(old)
            return fn(*args, **kwargs)

        return inner

    return wrap
