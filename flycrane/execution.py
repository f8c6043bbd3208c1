"""Where CPU-heavy jobs (planning runs, benchmark seeds) execute: one small interface.

The interface is :class:`concurrent.futures.Executor` (``submit(fn, *args) -> Future``).
The default is a local process pool; a distributed engine takes over by passing its own
Executor (for example ``dask.distributed.Client(...).get_executor()``). Jobs and their
arguments must therefore be picklable top-level functions and plain data.

Processes start with the *spawn* method: fork would copy the parent's threads and locks
(the service runs an event loop and database threads), and OMPL must run in a fresh
process (see :mod:`flycrane.planning.ompl_peers`).

Workers die with their parent, however it ends (kill -9 included): each watches the parent
process through a pidfd (Linux >= 5.3; elsewhere by polling its parent's pid) and exits when
it is gone. Without this a worker goes on planning for nobody, and the spawn pool's workers
inherit no pipe whose end they could see. ``PR_SET_PDEATHSIG`` is not used: it fires when
the *thread* that started the worker exits, and pools start workers from whichever thread
submits.
"""

from __future__ import annotations

import multiprocessing
import os
import select
import threading
import time
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any

#: How often a worker without pidfd support looks at its parent's pid [s].
PARENT_POLL_INTERVAL = 0.5


def available_workers() -> int:
    """CPUs this process may use (respects affinity masks, e.g. in containers)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def exit_with_parent(parent: int) -> None:
    """Start a daemon thread that ends this process as soon as process ``parent`` has ended.

    Runs as the pool's initializer in every worker (module docstring).
    """

    def watch() -> None:
        try:
            handle = os.pidfd_open(parent)
        except (AttributeError, OSError):  # no pidfd here, or the parent is already gone
            while os.getppid() == parent:
                time.sleep(PARENT_POLL_INTERVAL)
        else:
            # The pid could have been reused before pidfd_open: the parent must still be ours.
            if os.getppid() == parent:
                select.select([handle], [], [])  # readable once the process has exited
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def local_executor(workers: int | None = None) -> Executor:
    """A process pool of ``workers`` (default: every available CPU), spawn start method,
    whose workers exit when this process does."""
    return ProcessPoolExecutor(
        max_workers=workers or available_workers(),
        mp_context=multiprocessing.get_context("spawn"),
        initializer=exit_with_parent,
        initargs=(os.getpid(),),
    )


def stop_executor(executor: Executor) -> None:
    """Stop an executor now: queued jobs are dropped and, for a local process pool, the
    running ones killed (``shutdown`` alone waits for them to finish, however long).

    Uses ``terminate_workers`` where Python has it (3.14), else the pool's process table.
    """
    executor.shutdown(wait=False, cancel_futures=True)
    if not isinstance(executor, ProcessPoolExecutor):
        return
    terminate: Any = getattr(executor, "terminate_workers", None)
    if terminate is not None:
        terminate()
        return
    processes: dict[int, Any] = dict(getattr(executor, "_processes", None) or {})
    for process in processes.values():
        process.kill()
    for process in processes.values():
        process.join(timeout=5)
