"""Bounded work: what the service refuses with 503 (a full queue, as many what-ifs as
allowed, a locked database, no worker pool) while /healthz and other requests go on.

Every request here is answered by the real application; the tasks are held or cancelled.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sqlite3
import threading
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

from fastapi.testclient import TestClient

from flycrane.world.scene import load_scene
from service.app import create_app
from service.settings import Settings
from tests.service.conftest import TEST_HOST, running_service


def test_a_locked_database_answers_503_and_other_requests_go_on(tmp_path):
    with running_service(tmp_path) as client:
        database = sqlite3.connect(tmp_path / "flycrane.db", isolation_level=None, timeout=1)
        database.execute("BEGIN EXCLUSIVE")  # as another process writing for 40 s would
        answers = {}
        post = threading.Thread(
            target=lambda: answers.update(post=client.post("/v1/tasks", json={"name": "x"}))
        )
        try:
            post.start()
            # The POST waits for the lock in a worker thread; the event loop stays free.
            health = client.get("/healthz")
            still_waiting = post.is_alive()
        finally:
            post.join(timeout=60)
            database.execute("ROLLBACK")
            database.close()
        assert health.status_code == 200 and still_waiting
        response = answers["post"]
        assert response.status_code == 503, response.text
        assert response.headers["retry-after"] == "5"
        assert "database is busy" in response.json()["detail"]
        assert client.get("/v1/tasks").json()["total"] == 0  # nothing half-stored


def test_health_tells_when_no_worker_pool_can_run_tasks(tmp_path):
    """A caller's pool (which the service cannot replace) broken by a killed worker:
    /healthz says so with 503, new tasks are refused with 503, the running one failed."""
    from tests.service.conftest import wait_finished, wait_status

    level = load_scene("puzzle")[0].model_dump(mode="json")
    level["bounds"]["max_tilt"] = 1e-3  # no path without tilt: it plans until cancelled
    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
    settings = Settings(data_dir=tmp_path, allowed_hosts=(TEST_HOST,))
    try:
        with TestClient(create_app(settings, pool)) as client:
            assert client.get("/healthz").status_code == 200
            body = {"scene": level, "planner": {"time_budget": 300}}
            task_id = client.post("/v1/tasks", json=body).json()["id"]
            wait_status(client, task_id, {"planning"})
            for process in list(pool._processes.values()):  # the test owns this pool
                os.kill(process.pid, signal.SIGKILL)
            task = wait_finished(client, task_id)
            assert task["status"] == "failed" and "worker" in task["error"]
            health = client.get("/healthz")
            assert health.status_code == 503 and health.json()["status"] == "unavailable"
            assert health.json()["problems"] == ["no usable worker pool"]
            assert client.post("/v1/tasks", json={"name": "later"}).status_code == 503
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


def test_concurrent_submissions_never_exceed_the_queue(tmp_path, monkeypatch):
    """Handlers run in parallel threads: of 8 simultaneous valid POSTs with room for 2,
    exactly 2 are accepted and 6 refused with 503 (the jobs are held, so none finishes)."""
    import missions.task.pipeline

    release = threading.Event()
    monkeypatch.setattr(missions.task.pipeline, "run_task", lambda *a, **k: release.wait(60))
    settings = Settings(data_dir=tmp_path, allowed_hosts=(TEST_HOST,), max_queued_tasks=2)
    with ThreadPoolExecutor(2) as pool, TestClient(create_app(settings, pool)) as client:
        with ThreadPoolExecutor(8) as senders:
            answers = list(senders.map(lambda n: client.post("/v1/tasks", json={}), range(8)))
        release.set()
        codes = sorted(a.status_code for a in answers)
        assert codes == [202, 202] + [503] * 6, codes
        assert all(a.headers["retry-after"] == "10" for a in answers if a.status_code == 503)


# -- what-ifs bounded; /healthz answered while every request thread is busy ------------------


def _fill_the_request_threads(client) -> tuple[int, int]:
    """Make the request threads (anyio's default limiter) exactly as many as are borrowed:
    one more request needing a thread waits. Returns (borrowed, total before)."""
    import anyio.to_thread

    def fill() -> tuple[int, int]:
        limiter = anyio.to_thread.current_default_thread_limiter()
        borrowed, total = int(limiter.borrowed_tokens), int(limiter.total_tokens)
        limiter.total_tokens = borrowed
        return borrowed, total

    return client.portal.call(fill)


def _restore_the_request_threads(client, total: int) -> None:
    import anyio.to_thread

    def restore() -> None:
        anyio.to_thread.current_default_thread_limiter().total_tokens = total

    client.portal.call(restore)


def test_what_ifs_beyond_the_limit_are_503_and_health_answers_with_every_thread_busy(
    tmp_path, monkeypatch
):
    """Enough what-ifs at once took every request thread, and /healthz waited for one. Now
    at most MAX_CONCURRENT_STATICS are computed (held here until the test releases them),
    the others are refused at once with 503; and with every request thread busy, /healthz
    still answers while a route that needs such a thread waits."""
    import service.api.routes.statics as statics_route

    computing, release, released = threading.Semaphore(0), threading.Event(), []
    real = statics_route.evaluate_statics

    def held(system, q):
        computing.release()
        released.append(release.wait(60))
        return real(system, q)

    monkeypatch.setattr(statics_route, "evaluate_statics", held)
    body = {"q": [[0, 0, 5, 0, 0, 0, 1, 1, 1]]}
    with (
        running_service(tmp_path, max_concurrent_statics=2) as client,
        ThreadPoolExecutor(3) as senders,
    ):
        running = [senders.submit(client.post, "/v1/statics", json=body) for _ in range(2)]
        try:
            assert computing.acquire(timeout=60) and computing.acquire(timeout=60)
            borrowed, total = _fill_the_request_threads(client)
            try:
                assert borrowed >= 2
                starved = senders.submit(client.get, "/v1/presets/systems")
                refused = client.post("/v1/statics", json=body)
                health = client.get("/healthz")
                assert not starved.done()  # it needs a request thread: none is free
            finally:
                _restore_the_request_threads(client, total)
        finally:
            release.set()
        answers = [r.result() for r in running]
        assert starved.result().status_code == 200
    assert refused.status_code == 503, refused.text
    assert refused.headers["retry-after"] == "1"
    assert refused.json()["detail"] == "2 statics requests are running; retry later"
    assert health.status_code == 200 and health.json()["status"] == "ok", health.text
    assert [a.status_code for a in answers] == [200, 200] and released == [True, True]
    assert answers[0].json()["results"][0]["feasible"]
