"""numba's ``njit`` as the package uses it: cached where numba can write the cache.

The cache goes to NUMBA_CACHE_DIR when set, else to the ``__pycache__`` beside the
compiled module. In a read-only site-packages the functions are compiled once per
process instead (a fraction of a second each), with no warning.
"""
from __future__ import annotations

import os

# numba's OpenMP thread pool (the ``prange`` sweeps of twolink.fqi._factored_kernel) spins
# while it waits by default: on a machine whose cores are busy with other work the
# spinning threads steal the time the working one needs, and a 0.3 ms sweep took 7-16 ms
# (measured with one other process running on this 2-core machine). Waiting passively
# costs nothing measurable on an idle machine. Set before the pool starts; a user's own
# setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402


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


def njit_parallel(module_file: str):
    """``numba.njit(cache=..., nogil=True, parallel=True)``: a function whose ``prange``
    loops run on numba's thread pool (one thread per core at most)."""
    return numba.njit(cache=cache_wanted(module_file), nogil=True, parallel=True)
