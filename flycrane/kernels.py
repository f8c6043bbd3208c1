"""How the hot loops that allocate nothing are compiled: numba, cached on disk, releasing
the GIL, and without reference counting.

Why without: numba counts a reference to every array of a tuple that compiled code takes
apart before a call, once per call, wherever it cannot prove the count balanced; the
checker's model and scratch tuples hold about forty arrays, and that counting was two
thirds of a planner's state check (BENCHMARKS.md "Compiled without reference counting").
A kernel compiled so may not allocate, nor may what it calls: numba refuses to compile one
that does, so the rule cannot be broken silently.

``inline="always"`` is for the parts of a state check: numba passes every array of a tuple
argument as its separate fields, so a call that takes the scene's tuple copies about 250
values; inlined, the parts of one check make no such call.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba


def kernel(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    """``numba.njit`` for an allocation-free kernel (module docstring); ``options`` are
    numba's (``error_model``, ``inline``)."""
    njit: Any = numba.njit  # its type stubs do not list _nrt, numba's option for this
    return njit(cache=True, nogil=True, _nrt=False, **options)
