"""Where CPU-heavy jobs (planning runs, benchmark seeds) execute: one small interface.

The interface is :class:`concurrent.futures.Executor` (``submit(fn, *args) -> Future``).
The default is a local process pool; a distributed engine takes over by passing its own
Executor (for example ``dask.distributed.Client(...).get_executor()``). Jobs and their
arguments must therefore be picklable top-level functions and plain data.

Processes start with the *spawn* method: fork would copy the parent's threads and locks
(the service runs an event loop and database threads), and OMPL must run in a fresh
process (see :mod:`flycrane.planning.ompl_peers`).
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import Executor, ProcessPoolExecutor


def available_workers() -> int:
    """CPUs this process may use (respects affinity masks, e.g. in containers)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def local_executor(workers: int | None = None) -> Executor:
    """A process pool of ``workers`` (default: every available CPU), spawn start method."""
    return ProcessPoolExecutor(
        max_workers=workers or available_workers(),
        mp_context=multiprocessing.get_context("spawn"),
    )
