"""Numba's compilation cache, made safe for every install: the compiled kernels (the learner's
and the crowd controllers) take their options here.

- **A cache where one can be written**: beside the package, or numba's user-wide folder, or
  ``NUMBA_CACHE_DIR``. Where none can be (a read-only install with a read-only HOME, a
  container, an unusable ``NUMBA_CACHE_DIR``), the kernels compile without a cache, said once.
- **A damaged cache is rebuilt**: a truncated, random or swapped cache file reads as a miss
  (said once), so numba compiles anew and writes over it, instead of every command failing
  until the user finds and deletes ``__pycache__``.
- **No numba at all** (absent, or built for another Python or NumPy): the learner still runs,
  STGAT on its tensor kernels (``model.kernels = auto`` resolves to ``tensor``, said once and
  written to the run card); only the simulators' controllers need numba.
"""

from __future__ import annotations

import sys
from functools import cache

try:  # the learner runs without numba (STGAT's tensor kernels); the simulators need it
    import numba
    from numba.core import caching
except ImportError as error:  # absent, or built for another Python or NumPy
    numba = caching = None
    MISSING = f"{type(error).__name__}: {str(error).splitlines()[0][:100]}"
else:
    MISSING = None

_said: set[str] = set()


def note(text: str) -> None:
    """``text`` on stderr, once a process."""
    if text not in _said:
        _said.add(text)
        print(f"note: {text}", file=sys.stderr)


@cache
def cache_usable() -> bool:
    """Whether numba can keep compiled kernels on disk here (probed once a process)."""
    if numba is None:
        return False
    try:
        numba.njit(cache=True)(_probe)
    except (RuntimeError, OSError) as error:
        note(
            f"numba cannot write a cache here ({str(error).splitlines()[0][:120]}): the kernels "
            "compile in every process (a few seconds); set NUMBA_CACHE_DIR to a writable folder "
            "to keep them"
        )
        return False
    return True


def _probe():  # pragma: no cover (compiled)
    return 0


def _tolerant(load):
    """A load of numba's cache with a damaged file read as a miss (``{}`` for an index, else
    None: numba compiles anew and writes over it); a kernel read from another function's file
    (files swapped) is damaged too."""

    def guarded(self, *args):
        try:
            loaded = load(self, *args)
            fndesc = getattr(loaded, "fndesc", None)
            if fndesc is not None and fndesc.qualname != self._py_func.__qualname__:
                raise TypeError(f"it holds {fndesc.qualname}")
            return loaded
        except Exception as error:  # unpickling damaged bytes raises whatever they hold
            path = getattr(self, "_index_path", None) or getattr(self, "_cache_path", "")
            note(
                f"numba's cache {path} is damaged ({type(error).__name__}); compiling anew and "
                "writing over it"
            )
            return {} if load.__name__ == "_load_index" else None

    guarded.__name__ = load.__name__
    guarded.tolerant = True
    return guarded


if caching is not None and not getattr(caching.Cache._load_overload, "tolerant", False):
    caching.Cache._load_overload = _tolerant(caching.Cache._load_overload)
    caching.IndexDataCacheFile._load_index = _tolerant(caching.IndexDataCacheFile._load_index)


def options(**extra) -> dict:
    """``njit``'s options with the cache where one can be written."""
    return {"cache": cache_usable(), **extra}


def njit(*args, **kwargs):
    """numba's ``njit``; where numba cannot be imported, the function itself (plain Python,
    which ``model.kernels`` never picks then: :func:`c2inet.kernels.resolve`)."""
    if numba is not None:
        return numba.njit(*args, **kwargs)
    if len(args) == 1 and callable(args[0]) and not kwargs:
        return args[0]
    return lambda function: function
