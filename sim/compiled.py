"""Compiled kernels of the simulator's hot loops: the one way they are compiled.

numba, nopython and without the GIL, cached on disk so that a fresh process loads the
machine code instead of compiling it (the first call of a kernel then costs milliseconds,
not a second). No ``fastmath``: the kernels must round exactly as the numpy they replaced,
so that the truth they compute stays bit for bit the same.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba

_F = TypeVar("_F", bound=Callable[..., Any])


def kernel(fn: _F) -> _F:
    """Compile ``fn`` with numba: nopython, cached on disk, without the GIL."""
    return cast(_F, numba.njit(cache=True, nogil=True)(fn))
