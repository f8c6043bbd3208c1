"""The service's tasks on a Dask cluster (FLYCRANE_EXECUTOR=dask://...): worker processes
that share only the PostgreSQL database with the service, not its disk. Progress, cancel
and the time budget go through the database; the artifacts come back with the result; a
worker killed mid-task fails its task with the reason and the service carries on."""

from __future__ import annotations

import os
import signal
import tomllib

import pytest
from distributed import Client

from flycrane.world.scene import SCENES_DIR
from service.worker import WORKER_DIED
from tests.service.conftest import running_service, wait_finished, wait_progress, wait_status

RESCUE = {"name": "rescue on dask", "planner": {"seed": 0, "time_budget": 60}}


def unsolvable(budget: float) -> dict:
    """The Puzzle without tilt has no path (tests/flycrane/test_scene.py): it plans until
    stopped or out of time."""
    level = tomllib.loads((SCENES_DIR / "puzzle.toml").read_text(encoding="utf-8"))
    level["bounds"]["max_tilt"] = 1e-3
    return {"scene": level, "planner": {"time_budget": budget}}


@pytest.fixture(scope="module")
def service(dask_cluster, postgres_server, tmp_path_factory):
    executor = dask_cluster.replace("tcp://", "dask://")
    data_dir = tmp_path_factory.mktemp("dask-service")
    url = postgres_server.new_database()
    with running_service(data_dir, database_url=url, executor=executor) as client:
        yield client, data_dir


def test_a_task_runs_on_the_cluster_and_its_artifacts_come_back(service):
    client, data_dir = service
    task_id = client.post("/v1/tasks", json=RESCUE).json()["id"]
    task = wait_finished(client, task_id)
    assert task["status"] == "done", task["error"]
    for name in ("drone1.waypoints", "drone3.parm", "mission.mcap", "summary.json"):
        assert name in task["artifacts"]
        assert (data_dir / "tasks" / task_id / name).is_file(), name
    assert client.get(f"/v1/tasks/{task_id}/bundle.zip").status_code == 200
    summary = client.get(f"/v1/tasks/{task_id}/artifacts/summary.json").json()
    assert summary["status"] == "done"


def test_progress_and_cancel_reach_a_job_on_another_process(service):
    client, _ = service
    task_id = client.post("/v1/tasks", json=unsolvable(300)).json()["id"]
    wait_status(client, task_id, {"planning"})
    progress = wait_progress(client, task_id)
    assert progress["nodes"] >= 1 and progress["elapsed"] > 0
    assert client.delete(f"/v1/tasks/{task_id}").json()["cancel_requested"]
    task = wait_finished(client, task_id, timeout=30)
    assert task["status"] == "cancelled" and task["result"]["planner_status"] == "cancelled"


def test_the_time_budget_holds_on_a_worker(service):
    client, _ = service
    task = wait_finished(client, client.post("/v1/tasks", json=unsolvable(2)).json()["id"])
    assert task["result"]["planner_status"] == "timeout", task
    # stopped by its 2 s budget (the planner's clock starts a moment after the reported
    # time's), not much later
    assert 1.9 <= task["result"]["planner_statistics"]["time"] < 10.0


def test_a_worker_killed_mid_task_fails_it_and_later_tasks_succeed(service, dask_cluster):
    client, _ = service
    task_id = client.post("/v1/tasks", json=unsolvable(300)).json()["id"]
    wait_progress(client, task_id)
    with Client(dask_cluster, set_as_default=False) as peer:
        busy = [worker for worker, keys in peer.processing().items() if keys]
        assert len(busy) == 1, peer.processing()
        pid = peer.run(os.getpid, workers=busy)[busy[0]]
    os.kill(pid, signal.SIGKILL)  # as the OOM killer would
    task = wait_finished(client, task_id, timeout=120)
    assert task["status"] == "failed" and task["error"] == WORKER_DIED
    after = wait_finished(client, client.post("/v1/tasks", json=RESCUE).json()["id"])
    assert after["status"] == "done", after["error"]
    assert client.get("/healthz").status_code == 200
