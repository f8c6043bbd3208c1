"""Faults, as an operator's machine produces them (issue 10, items 3 and 10).

A real ``uvicorn`` server in its own session on a loopback port, one worker process:

- a worker killed with SIGKILL mid-task (as the OOM killer would): that task fails with the
  reason, the pool is replaced, health stays true, and a later task is planned to the end;
- the server killed with SIGKILL mid-task: its worker and helper processes end with it
  (checked by PID), a restarted server lists every task as it was and resumes the one that
  was running; stopped with SIGTERM, it leaves no process behind either.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import httpx

from flycrane.world.scene import load_scene
from tests.service.conftest import wait_finished, wait_status
from tests.service.live import Server, start_server

#: The Puzzle without tilt has no path (tests/flycrane/test_scene.py): it plans until stopped.
_LEVEL = load_scene("puzzle")[0].model_dump(mode="json")
_LEVEL["bounds"]["max_tilt"] = 1e-3
ENDLESS = {"name": "endless", "scene": _LEVEL, "planner": {"time_budget": 300}}
RESCUE = {"name": "rescue", "planner": {"seed": 0}}
#: How long processes may take to go once their parent is gone [s] (a bound, not a speed).
GONE_WITHIN = 30.0


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (children, their children, ...), from /proc."""
    found: set[int] = set()
    frontier = [pid]
    while frontier:
        parent = frontier.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = (task / "children").read_text().split()
            except OSError:
                continue
            for child in map(int, children):
                if child not in found:
                    found.add(child)
                    frontier.append(child)
    return found


def alive(pid: int) -> bool:
    """Running (a zombie waiting for its parent to reap it counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def workers(server: Server) -> set[int]:
    """The server's planning processes (spawned pool workers)."""
    return {p for p in descendants(server.pid) if "spawn_main" in cmdline(p)}


def wait_gone(pids: set[int], timeout: float = GONE_WITHIN) -> set[int]:
    """The processes of ``pids`` still running after ``timeout`` (empty: all gone)."""
    deadline = time.monotonic() + timeout
    while (left := {p for p in pids if alive(p)}) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left


def submit(client: httpx.Client, body: dict) -> str:
    response = client.post("/v1/tasks", json=body)
    assert response.status_code == 202, response.text
    return response.json()["id"]


def test_worker_death_then_server_death_lose_nothing_and_leave_no_process(tmp_path):
    server = start_server(tmp_path)
    try:
        # -- a worker dies mid-task ---------------------------------------------------------
        killed = submit(server.client, ENDLESS)
        wait_status(server.client, killed, {"planning"})
        (worker,) = workers(server)
        os.kill(worker, signal.SIGKILL)
        task = wait_finished(server.client, killed)
        assert task["status"] == "failed" and "worker process" in task["error"], task
        health = server.client.get("/healthz")
        assert health.status_code == 200, health.text
        assert health.json()["replaced_pools"] == 1
        later = wait_finished(server.client, submit(server.client, RESCUE), timeout=180)
        assert later["status"] == "done", later["error"]

        # -- the server dies mid-task -------------------------------------------------------
        running = submit(server.client, ENDLESS)
        wait_status(server.client, running, {"planning"})
        before = {t["id"]: t["status"] for t in server.client.get("/v1/tasks").json()["items"]}
        processes = descendants(server.pid)
        assert workers(server) and workers(server) <= processes
        server.stop(signal.SIGKILL)
        assert wait_gone(processes) == set(), [cmdline(p) for p in processes if alive(p)]
    finally:
        server.stop(signal.SIGKILL)

    server = start_server(tmp_path)
    try:
        after = {t["id"]: t for t in server.client.get("/v1/tasks").json()["items"]}
        assert set(after) == set(before) == {killed, later["id"], running}
        for task_id in (killed, later["id"]):
            assert after[task_id]["status"] == before[task_id]
        assert after[running]["status"] in ("queued", "planning")  # resumed
        assert server.client.get(f"/v1/tasks/{later['id']}/artifacts/summary.json").is_success
        wait_status(server.client, running, {"planning"})
        processes = descendants(server.pid)
        server.stop(signal.SIGTERM)
        assert server.process.returncode is not None
        assert wait_gone(processes) == set(), [cmdline(p) for p in processes if alive(p)]
    finally:
        server.stop(signal.SIGKILL)
