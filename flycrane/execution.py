"""Where CPU-heavy jobs (planning runs, benchmark seeds) execute: one small interface.

The interface is :class:`concurrent.futures.Executor` (``submit(fn, *args) -> Future``).
The default is a local process pool; :func:`dask_executor` runs the same jobs on a Dask
distributed cluster (:class:`DaskExecutor`: a scheduler and workers on any hosts, or a
``LocalCluster``), and :func:`executor_for` picks one from an address. Jobs and their
arguments must therefore be picklable top-level functions and plain data, and a job must not
assume that its caller's disk is its own.

Processes start with the *spawn* method: fork would copy the parent's threads and locks
(the service runs an event loop and database threads), and OMPL must run in a fresh
process (see :mod:`flycrane.planning.algorithms.ompl_peers`).

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
import signal
import threading
import time
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any

#: Most worker processes of a local pool: each is a process with its own compiled kernels.
MAX_WORKERS = 256
#: How often a worker without pidfd support looks at its parent's pid [s].
PARENT_POLL_INTERVAL = 0.5


def available_workers() -> int:
    """CPUs this process may use (respects affinity masks, e.g. in containers)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def start_worker(parent: int) -> None:
    """The pool's initializer in every worker: a terminal's Ctrl-C (SIGINT to the whole
    process group) is the parent's to act on, not the worker's (the service leaves a
    running task to be run again at its next start, a benchmark ends, and the workers end
    with their parent: :func:`exit_with_parent`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent(parent)


def exit_with_parent(parent: int) -> None:
    """Start a daemon thread that ends this process as soon as process ``parent`` has ended
    (module docstring)."""

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
        initializer=start_worker,
        initargs=(os.getpid(),),
    )


class DaskExecutor(Executor):
    """Jobs on the Dask cluster at ``address`` (``tcp://host:8786``), through the client's
    concurrent.futures interface, with the client it owns.

    Every submission is a task of its own (``pure=False``: two equal submissions, e.g. a
    task run again after a restart, must both run). A cancelled future that is already
    running goes on in its worker: jobs must stop themselves (the service's poll their
    task's cancel flag). When a worker dies, the scheduler runs its tasks again on another
    worker (up to its ``allowed-failures``), so a job may start twice.
    """

    def __init__(self, address: str, timeout: float | None = None) -> None:
        """``timeout`` [s] to connect; None: Dask's ``distributed.comm.timeouts.connect``
        (30 s unless configured, e.g. ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s``)."""
        from distributed import Client

        self.address = address
        waits = {} if timeout is None else {"timeout": timeout}
        self.client = Client(address, set_as_default=False, **waits)
        self._executor = self.client.get_executor(pure=False)

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Any:
        return self._executor.submit(fn, *args, **kwargs)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._executor.shutdown(wait=wait and not cancel_futures)
        self.client.close()


def scheduler_address(text: str) -> str:
    """A Dask scheduler's address as Dask takes it: ``tcp://host:port``, ``dask://`` read as
    ``tcp://``. Checked before a client is made: Dask's own error for a malformed address
    comes as a traceback, then a minute's wait in the client's cleanup. ``tls://`` is
    refused: it needs a Dask security configuration (certificates) this client is not given.

    Raises
    ------
    ValueError
        Not one of these schemes, or no host, or a port not in 1..65535.
    """
    scheme, separator, rest = text.partition("://")
    if scheme == "tls":
        raise ValueError(
            f"{text!r}: TLS needs certificates this client is not given; reach the scheduler "
            "over tcp:// on a private network (or through a tunnel)"
        )
    if not separator or scheme not in ("dask", "tcp"):
        raise ValueError(f"{text!r} is not a scheduler address, tcp://host:port")
    host, colon, port = rest.rpartition(":")
    if not (colon and host and port.isdigit() and 0 < int(port) < 65536):
        raise ValueError(f"{text!r} has no host, or no port in 1..65535 (tcp://host:8786)")
    return f"tcp://{rest}" if scheme == "dask" else text


def executor_for(address: str | None, workers: int | None = None) -> Executor:
    """The local process pool of ``workers`` for no address (or ``"local"``), the Dask cluster
    at a scheduler address (``tcp://host:port``) otherwise."""
    if not address or address == "local":
        return local_executor(workers)
    return DaskExecutor(scheduler_address(address))


def stop_executor(executor: Executor) -> None:
    """Stop an executor now: queued jobs are dropped and, for a local process pool, the
    running ones killed (``shutdown`` alone waits for them to finish, however long).

    Uses ``terminate_workers`` where Python has it (3.14), else the pool's process table,
    read before ``shutdown``, which empties it: read after, it would leave the running jobs
    of a stopped server alive to write into the rows its next start resumes.
    """
    processes: dict[int, Any] = dict(getattr(executor, "_processes", None) or {})
    executor.shutdown(wait=False, cancel_futures=True)
    if not isinstance(executor, ProcessPoolExecutor):
        return
    terminate: Any = getattr(executor, "terminate_workers", None)
    if terminate is not None:
        terminate()
        return
    for process in processes.values():
        process.kill()
    for process in processes.values():
        process.join(timeout=5)
