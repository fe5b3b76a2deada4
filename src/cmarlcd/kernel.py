"""The decorator of the compiled kernels that games and learners hand to the loops.

A kernel is an ``@njit`` function, cached on disk, that allocates nothing and is
compiled without numba's reference counting (``_nrt=False``). Kernels take tuples of
arrays (a game's state arrays, a learner's tables), and numba counts a reference every
time a function takes an array out of a tuple: atomic operations that cost about a
tenth of a DSN step when every kernel call pays them. A kernel that needs no memory of
its own needs no reference counting; one that allocates (``np.zeros`` and the like)
fails to compile with ``kernel`` and must use plain ``@njit``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numba import njit


def kernel(function: Callable) -> Any:
    """Compile ``function`` as a kernel (see the module docstring)."""
    return njit(cache=True, _nrt=False)(function)
