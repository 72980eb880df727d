"""numba's ``njit`` as the package uses it: cached where numba can write the cache.

The cache goes to NUMBA_CACHE_DIR when set, else to the ``__pycache__`` beside the
compiled module. In a read-only site-packages the functions are compiled once per
process instead (a fraction of a second each), with no warning.
"""
from __future__ import annotations

import os

import numba


def cache_wanted(module_file: str) -> bool:
    """Whether numba can write the cache of functions defined in ``module_file``."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True
    here = os.path.dirname(os.path.abspath(module_file))
    pycache = os.path.join(here, "__pycache__")
    return os.access(pycache if os.path.isdir(pycache) else here, os.W_OK)


def njit(module_file: str):
    """``numba.njit(cache=..., nogil=True)`` for functions of ``module_file``."""
    return numba.njit(cache=cache_wanted(module_file), nogil=True)
