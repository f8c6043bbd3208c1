"""Benchmark runs on a Dask cluster of separate worker processes give, seed for seed, what
the local process pool gives (planning is deterministic per seed)."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import wait
from pathlib import Path

import pytest

from flycrane.analysis.benchmark import run_benchmark
from flycrane.execution import (
    DaskExecutor,
    executor_for,
    local_executor,
    scheduler_address,
    stop_executor,
)

#: Columns that depend on the seed only (times depend on the machine).
SEEDED = ("scene", "planner", "seed", "status", "nodes", "attempts", "avg_cost", "max_cost")


def records_by_seed(executor) -> dict:
    with executor:
        records = run_benchmark(executor, ["rescue"], ["trrt", "rrt"], 3, 30.0)
        return {(r.scene, r.planner, r.seed): r for r in records}


def test_the_cluster_runs_each_seed_as_the_local_pool_does(dask_cluster):
    on_cluster = records_by_seed(executor_for(dask_cluster))
    local = records_by_seed(local_executor(2))
    assert on_cluster.keys() == local.keys() and len(local) == 6
    for key, record in local.items():
        other = on_cluster[key]
        assert record.status == "exact_solution", key
        assert [getattr(other, c) for c in SEEDED] == [getattr(record, c) for c in SEEDED], key
        assert other.path == record.path, key


def test_the_jobs_ran_in_the_cluster_workers(dask_cluster):
    with DaskExecutor(dask_cluster) as executor:
        pids = {executor.submit(os.getpid).result(timeout=60) for _ in range(8)}
        workers = set(executor.client.run(os.getpid).values())
    assert pids <= workers and os.getpid() not in pids


def test_bench_command_on_the_cluster(dask_cluster, tmp_path: Path):
    def bench(out: Path, *where: str) -> list[dict]:
        command = [sys.executable, "-m", "flycrane.cli", "bench", "--scenes", "rescue",
                   "--planners", "trrt", "--runs", "2", "--budget", "30", "--out", str(out),
                   *where]  # fmt: skip
        subprocess.run(command, check=True, capture_output=True, timeout=300)
        with (out / "runs.csv").open() as f:
            return [{c: row[c] for c in SEEDED} for row in csv.DictReader(f)]

    assert bench(tmp_path / "cluster", "--cluster", dask_cluster) == bench(
        tmp_path / "local", "--workers", "2"
    )


def test_an_unreachable_cluster_is_a_message_not_a_traceback(tmp_path: Path):
    command = [sys.executable, "-m", "flycrane.cli", "bench", "--scenes", "rescue", "--runs",
               "1", "--out", str(tmp_path), "--cluster", "tcp://127.0.0.1:9"]  # fmt: skip
    # Dask gives up connecting after 30 s by default; the message is what is tested here.
    quick = {**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "2s"}
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, env=quick)
    assert done.returncode == 2, done.stderr
    assert "tcp://127.0.0.1:9" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize("address", [None, "", "local"])
def test_no_address_is_the_local_pool(address):
    with executor_for(address, 1) as executor:
        assert not isinstance(executor, DaskExecutor)
        assert executor.submit(os.getpid).result(timeout=60) != os.getpid()


def _report_pid_then_sleep(seconds: float) -> None:
    Path(os.environ["FLYCRANE_TEST_PID_FILE"]).write_text(str(os.getpid()))
    time.sleep(seconds)


def test_stopping_a_local_pool_kills_its_running_job(tmp_path, monkeypatch):
    """A stopped server must leave no job running: one that lived on wrote into the rows
    its next start resumed. The worker's pid is probed with the OS, not the pool."""
    pid_file = tmp_path / "pid"
    monkeypatch.setenv("FLYCRANE_TEST_PID_FILE", str(pid_file))
    executor = local_executor(1)
    future = executor.submit(_report_pid_then_sleep, 600.0)
    deadline = time.monotonic() + 120
    while not pid_file.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    pid = int(pid_file.read_text())
    stop_executor(executor)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        os.kill(pid, signal.SIGKILL)
        pytest.fail(f"worker {pid} still running after stop_executor")
    # The pool's own thread ends the future once it sees its worker gone: soon, not at once.
    assert wait([future], timeout=30).done == {future}


def _interrupted() -> int:
    """A terminal's Ctrl-C, as a worker in the terminal's process group gets it."""
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.2)
    return os.getpid()


def test_a_ctrl_c_is_the_parent_s_not_the_worker_s():
    """Ctrl-C on `flycrane serve` reached the worker too: its KeyboardInterrupt failed the
    running task for good, where the server's own shutdown leaves it to be run again."""
    with local_executor(1) as executor:
        try:
            assert executor.submit(_interrupted).result(timeout=60) != os.getpid()
        except KeyboardInterrupt:  # the worker's, sent back as the job's outcome
            pytest.fail("the worker took the Ctrl-C")


@pytest.mark.parametrize(
    ("address", "expected"),
    [("tcp://10.0.0.5:8786", "tcp://10.0.0.5:8786"), ("dask://host:8786", "tcp://host:8786"),
     ("tcp://[::1]:8786", "tcp://[::1]:8786")],
)  # fmt: skip
def test_scheduler_addresses_as_dask_takes_them(address, expected):
    assert scheduler_address(address) == expected


@pytest.mark.parametrize("address", ["garbage", "tcp://host", "tcp://:8786", "udp://h:1",
                                     "tcp://h:0", "tcp://h:65536", "tcp://h:port"])  # fmt: skip
def test_a_malformed_scheduler_address_is_refused_before_a_client_is_made(address):
    with pytest.raises(ValueError, match=r"scheduler address|port in 1\.\.65535"):
        scheduler_address(address)


def test_a_tls_scheduler_is_refused_for_want_of_certificates():
    """Dask took it and failed with a TypeError traceback, then a minute's wait."""
    with pytest.raises(ValueError, match="TLS needs certificates"):
        scheduler_address("tls://10.0.0.5:8786")
