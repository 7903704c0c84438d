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

__all__ = ["renamed_keywords", "grouped_keywords"]


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


def grouped_keywords(param: str, cls):
    """Decorator: the loose keywords that became fields of the frozen dataclass ``cls`` (passed
    whole as ``param=``) still work, with a :class:`DeprecationWarning` at the caller's line;
    they replace those fields of the ``param=`` given (or of the function's default).

    >>> import dataclasses
    >>> @dataclasses.dataclass(frozen=True)
    ... class Stop:
    ...     max_iterations: int = 10
    ...     rtol: float = 1e-6
    >>> @grouped_keywords("stop", Stop)
    ... def f(x, stop=Stop()):
    ...     return stop
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     f(1, rtol=0.5), str(w[0].message)
    (Stop(max_iterations=10, rtol=0.5), 'f(rtol=) is now a field of Stop, passed as stop= (the loose keyword will go)')
    """
    import dataclasses
    import inspect

    fields = {f.name for f in dataclasses.fields(cls)}

    def wrap(fn):
        params = inspect.signature(fn).parameters
        default = params[param].default
        loose_names = fields - set(params)

        @functools.wraps(fn)
        def inner(*args, **kwargs):
            loose = {k: kwargs.pop(k) for k in list(kwargs) if k in loose_names}
            if loose:
                warnings.warn(f"{fn.__name__}({'=, '.join(loose)}=) is now a field of "
                              f"{cls.__name__}, passed as {param}= (the loose keyword will go)",
                              DeprecationWarning, stacklevel=2)
                base = kwargs.get(param)
                if base is None:
                    base = default if isinstance(default, cls) else cls()
                kwargs[param] = dataclasses.replace(base, **loose)
            return fn(*args, **kwargs)

        return inner

    return wrap
