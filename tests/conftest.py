"""Shared fixtures: the default benchmark system and random feasible configurations."""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import settings

from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import evaluate_statics
from tests.postgres import PostgresServer, PostgresUnavailable

# Timing is for benchmarks, not tests: the first call of a compiled kernel loads it from the
# numba cache, which would trip hypothesis' per-example deadline. Derandomized so that a run
# on CI draws the examples every run before it drew: a new counterexample is found by
# `pytest --hypothesis-seed=random` on purpose, never by chance in a submission's CI run.
settings.register_profile("flycrane", deadline=None, print_blob=True, derandomize=True)
settings.load_profile("flycrane")


@pytest.fixture(scope="session")
def system() -> CableSystem:
    return CableSystem.from_spec()


def random_configurations(rng: np.random.Generator, n: int, max_tilt: float = 0.6) -> np.ndarray:
    """Configurations around the hover pose: any position and heading, tilt and alphas spread."""
    q = np.empty((n, 9))
    q[:, :3] = rng.uniform([-20, -20, 2], [20, 20, 30], (n, 3))
    q[:, 3] = rng.uniform(-np.pi, np.pi, n)
    q[:, 4] = rng.uniform(0.0, max_tilt, n)
    q[:, 5] = rng.uniform(-np.pi, np.pi, n)
    q[:, 6:] = rng.uniform(0.3, 1.8, (n, 3))
    return q


def random_feasible_configurations(
    system: CableSystem, rng: np.random.Generator, n: int
) -> np.ndarray:
    """n feasible configurations by rejection sampling (feasibility by the numpy reference)."""
    found: list[np.ndarray] = []
    while sum(len(f) for f in found) < n:
        q = random_configurations(rng, 4 * n)
        found.append(q[evaluate_statics(system, q).feasible])
    return np.concatenate(found)[:n]


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[PostgresServer]:
    """A private PostgreSQL server for the session (tests/postgres.py); skips where none
    can be started, saying why."""
    try:
        server = PostgresServer()
    except PostgresUnavailable as reason:
        pytest.skip(f"PostgreSQL: {reason}")
    try:
        yield server
    finally:
        server.stop()


@pytest.fixture(scope="module", params=["sqlite", "postgresql"])
def backend(request: pytest.FixtureRequest) -> str:
    """The database engine a module's service and storage tests run on, each in turn."""
    if request.param == "postgresql":
        request.getfixturevalue("postgres_server")
    return str(request.param)


def database_url_for(backend: str, request: pytest.FixtureRequest) -> str | None:
    """A new empty database on ``backend``: its URL, or None for the service's default
    SQLite file in its data directory."""
    if backend == "sqlite":
        return None
    return request.getfixturevalue("postgres_server").new_database()


@pytest.fixture
def database_url(backend: str, request: pytest.FixtureRequest) -> str | None:
    """A new empty database of this test's backend (:func:`database_url_for`)."""
    return database_url_for(backend, request)


@pytest.fixture(scope="module")
def dask_cluster() -> Iterator[str]:
    """A Dask LocalCluster of two single-threaded worker processes on loopback (its
    scheduler's address); closed at the end of the module, every worker process checked
    gone by its PID."""
    import psutil
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    try:
        yield cluster.scheduler_address
    finally:
        with Client(cluster.scheduler_address, set_as_default=False) as client:
            pids = list(client.run(os.getpid).values())
        cluster.close(timeout=30)
        processes = [psutil.Process(pid) for pid in pids if psutil.pid_exists(pid)]
        _, alive = psutil.wait_procs(processes, timeout=10)
        for process in alive:
            process.kill()
        assert not alive, f"Dask workers outlived their cluster: {[p.pid for p in alive]}"
