"""Bad input gets the right status and a message naming the problem; nothing is stored."""

from __future__ import annotations

import numpy as np
import pytest

from tests.service.conftest import running_service

RESCUE_START = [0, 0, 0.45, 0, 0, np.pi / 2, 1, 1, 1]


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("errors"), max_request_bytes=20_000) as c:
        yield c


@pytest.mark.parametrize(
    ("body", "location", "message"),
    [
        ({"system": "nonesuch"}, ["body", "system"], "unknown preset 'nonesuch'"),
        ({"scene": "atlantis"}, ["body", "scene"], "no scene 'atlantis'"),
        ({"system": {"platform_mass": -1}}, ["body", "system", "platform_mass"], "greater than 0"),
        (
            {"system": {"perturbation": {"matrix": (-np.eye(6)).tolist()}}},
            ["body", "system", "perturbation", "matrix"],
            "positive definite",
        ),
        ({"start": [*RESCUE_START[:6], 1.45, 1.45, 1.45]}, ["body", "start"], "lowest tension"),
        ({"goal": [0, 0, 7.0, 0, 0, 0, 1, 1, 1]}, ["body", "goal"], "footbridge hits"),
        ({"planner": {"time_budget": 10_000}}, ["body", "planner", "time_budget"], "at most"),
        ({"planner": {"improve_time": 3_000}}, ["body", "planner", "improve_time"], "at most"),
        ({"planner": {"algorithm": "astar"}}, ["body", "planner", "algorithm"], "trrt"),
        ({"colour": "red"}, ["body", "colour"], "not permitted"),
    ],
)
def test_bad_task_is_refused_naming_the_field(client, body, location, message):
    before = client.get("/v1/tasks").json()["total"]
    response = client.post("/v1/tasks", json=body)
    assert response.status_code == 422, response.text
    details = response.json()["detail"]
    assert any(d["loc"][: len(location)] == location and message in d["msg"] for d in details), (
        details
    )
    assert client.get("/v1/tasks").json()["total"] == before


def test_malformed_json_and_oversized_body(client):
    response = client.post(
        "/v1/tasks", content=b'{"scene": ', headers={"content-type": "application/json"}
    )
    assert response.status_code == 422 and "JSON" in response.text
    big = {
        "name": "x" * 100,
        "scene": {
            "bounds": {"position_low": [0, 0, 0], "position_high": [1, 1, 1]},
            "start": RESCUE_START,
            "goal": RESCUE_START,
            "obstacles": [{"kind": "sphere", "radius": 1.0}] * 2000,
        },
    }
    response = client.post("/v1/tasks", json=big)
    assert response.status_code == 413 and "larger than 20000 bytes" in response.text
    assert client.get("/v1/tasks").json()["total"] == 0


def test_unknown_task_and_artifact(client):
    assert client.get("/v1/tasks/nope").status_code == 404
    assert "no task 'nope'" in client.get("/v1/tasks/nope").json()["detail"]
    assert client.delete("/v1/tasks/nope").status_code == 404
    assert client.get("/v1/tasks/nope/artifacts/summary.json").status_code == 404
    response = client.post("/v1/tasks/nope/upload", json={"vehicles": ["udp:127.0.0.1:1"] * 3})
    assert response.status_code == 404


def test_statics_what_if(client):
    response = client.post(
        "/v1/statics", json={"q": [[0, 0, 5, 0, 0, 0, 1, 1, 1], [0, 0, 5, 0, 0, 0, 1.4, 1.4, 1.4]]}
    )
    assert response.status_code == 200
    feasible, slack = response.json()["results"]
    assert feasible["feasible"] and feasible["cables"][0]["nominal_tension"] == pytest.approx(
        3.11, abs=0.01
    )
    assert not slack["feasible"] and slack["violations"][0]["constraint"] == "slack"
    bad = client.post("/v1/statics", json={"q": [[0, 0, 5]]})
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"][:2] == ["body", "q"]


def test_statics_errors_name_the_field_as_posted(client):
    """The first of a batch was named q.theta (no index), and a system the model refuses
    by the system's own field, geometry."""
    tilted = [0, 0, 5, 0, -1, 0, 1, 1, 1]
    for q, named in (([tilted], [[0, 4]]), ([tilted, tilted], [[0, 4], [1, 4]])):
        response = client.post("/v1/statics", json={"q": q})
        assert response.status_code == 422
        assert [d["loc"][2:] for d in response.json()["detail"]] == named
    flat = {"geometry": {"kind": "octahedral", "side": 1e-9}}
    response = client.post("/v1/statics", json={"q": [[0, 0, 5, 0, 0, 0, 1, 1, 1]], "system": flat})
    assert response.status_code == 422, response.text
    assert response.json()["detail"][0]["loc"][1:] == ["system", "geometry"]


def test_presets_health_and_metrics(client):
    assert "benchmark" in client.get("/v1/presets/systems").json()
    scenes = client.get("/v1/presets/scenes").json()
    assert {"rescue", "puzzle"} <= set(scenes)
    assert scenes["rescue"]["payload"]["shapes"][0]["name"] == "footbridge"
    assert client.get("/healthz").json()["status"] == "ok"
    metrics = client.get("/metrics").text
    assert 'flycrane_tasks{status="done"}' in metrics
    assert 'flycrane_task_submissions_total{outcome="invalid"}' in metrics
    assert client.get("/openapi.json").json()["paths"]["/v1/tasks"]["post"]


TOKEN = "a-long-enough-token-0123"
READ_TOKEN = "a-read-only-token-456789"


def test_tokens_guard_every_task_endpoint(tmp_path):
    """With a token set, writes need it and reads need it or the read token (issue 10,
    item 5: reads, missions with positions and MCAP logs included, were open)."""
    with running_service(tmp_path, api_token=TOKEN, read_token=READ_TOKEN) as client:
        writer = {"Authorization": f"Bearer {TOKEN}"}
        reader = {"Authorization": f"Bearer {READ_TOKEN}"}
        assert client.post("/v1/tasks", json={"scene": "atlantis"}).status_code == 401
        wrong = {"Authorization": "Bearer guess"}
        assert client.post("/v1/tasks", json={}, headers=wrong).status_code == 401
        assert client.post("/v1/tasks", json={}, headers=reader).status_code == 401
        assert client.delete("/v1/tasks/x").status_code == 401
        assert (
            client.post("/v1/tasks", json={"scene": "atlantis"}, headers=writer).status_code == 422
        )
        for path in ("/v1/tasks", "/v1/tasks/x", "/v1/tasks/x/artifacts/summary.json",
                     "/v1/tasks/x/bundle.zip", "/v1/viewer", "/v1/tasks/x/view.json"):  # fmt: skip
            response = client.get(path)
            assert response.status_code == 401, path
            assert response.headers["www-authenticate"] == "Bearer"
            assert client.get(path, headers=reader).status_code in (200, 404), path
            assert client.get(path, headers=writer).status_code in (200, 404), path
        # What carries no task data stays open: liveness, metrics, presets.
        for path in ("/healthz", "/metrics", "/v1/presets/scenes"):
            assert client.get(path).status_code == 200, path


def test_public_reads_open_reading_only(tmp_path):
    with running_service(tmp_path, api_token=TOKEN, public_reads=True) as client:
        assert client.get("/v1/tasks").status_code == 200
        assert client.post("/v1/tasks", json={}).status_code == 401


@pytest.mark.parametrize(
    ("settings", "field"),
    [
        ({"api_token": ""}, "api_token"),
        ({"api_token": "   "}, "api_token"),
        ({"api_token": "short"}, "api_token"),
        ({"read_token": READ_TOKEN}, "read_token\n  Value error, needs FLYCRANE_API_TOKEN"),
    ],
)
def test_an_empty_or_weak_token_is_refused_not_ignored(tmp_path, settings, field):
    from pydantic import ValidationError

    from service.settings import Settings

    with pytest.raises(ValidationError) as info:
        Settings(data_dir=tmp_path, **settings)
    assert field in str(info.value)


@pytest.mark.parametrize(
    ("settings", "reason"),
    [
        ({"data_dir": ""}, "data_dir\n  Value error, an empty name"),
        ({"allowed_hosts": ()}, "allowed_hosts\n  Value error, no host"),
        ({"database_url": "sqlite://"}, "database_url\n  Value error, an in-memory"),
        ({"database_url": "sqlite:///:memory:"}, "database_url\n  Value error, an in-memory"),
        ({"max_time_budget": float("inf")}, "max_time_budget\n  Input should be less than"),
        ({"workers": 257}, "workers\n  Input should be less than or equal to 256"),
    ],
)
def test_settings_a_server_could_not_work_with_are_refused(settings, reason):
    """Each started a server that quietly used the current directory, refused every
    request with 400, or lost every task (the workers see another in-memory database)."""
    from pydantic import ValidationError

    from service.settings import Settings

    with pytest.raises(ValidationError) as info:
        Settings(**settings)
    assert reason in str(info.value)


@pytest.mark.parametrize("value", ["none", "None", ""])
def test_retention_none_keeps_finished_tasks(monkeypatch, value):
    """The README said 'unset it to keep them', but unset is the default, 30 days."""
    from service.settings import Settings

    monkeypatch.setenv("FLYCRANE_RETENTION_DAYS", value)
    assert Settings().retention_days is None
    monkeypatch.delenv("FLYCRANE_RETENTION_DAYS")
    assert Settings().retention_days == 30.0


@pytest.mark.parametrize(
    ("executor", "scheduler"),
    [("local", None), ("dask://10.0.0.5:8786", "tcp://10.0.0.5:8786"),
     ("tls://host:8786", None), ("dask://host", None), ("tcp://:8786", None),
     ("dask://host:99999", None), ("garbage", None)],
)  # fmt: skip
def test_the_executor_is_local_or_a_whole_scheduler_address(tmp_path, executor, scheduler):
    """A scheduler without a port used to pass, and Dask's client then failed at start-up
    with a traceback."""
    from pydantic import ValidationError

    from service.settings import Settings

    if scheduler is None and executor != "local":
        with pytest.raises(ValidationError, match="executor"):
            Settings(data_dir=tmp_path, executor=executor)
        return
    assert Settings(data_dir=tmp_path, executor=executor).dask_scheduler == scheduler


@pytest.mark.parametrize(
    ("patterns", "why"),
    [(["["], "'[' is not a regular expression: unterminated character set"),
     ([r"/dev/ttyUSB[0-9]+", "(?P<x"], "'(?P<x' is not a regular expression")],
)  # fmt: skip
def test_an_upload_device_pattern_that_does_not_compile_is_refused(tmp_path, patterns, why):
    """It was accepted, and every upload then answered 500 (re.error)."""
    from pydantic import ValidationError

    from service.settings import Settings

    with pytest.raises(ValidationError) as info:
        Settings(data_dir=tmp_path, upload_devices=patterns)
    (problem,) = info.value.errors()
    assert problem["loc"] == ("upload_devices",) and why in problem["msg"], problem


@pytest.mark.parametrize(
    ("url", "why"),
    [("bogus://", "Can't load plugin: sqlalchemy.dialects:bogus"),
     ("not a url", "Could not parse SQLAlchemy URL"),
     ("postgresql://user:hunter2@host:port/db", "not a database URL SQLAlchemy can use"),
     ("postgresql+asyncpg://user:hunter2@host/db", "asyncpg is an asyncio driver")],
)  # fmt: skip
def test_a_database_url_sqlalchemy_cannot_use_is_refused_naming_the_setting(tmp_path, url, why):
    """It ended the start in a traceback (NoSuchModuleError, ArgumentError); the refusal
    never quotes the URL, which may hold a password."""
    from pydantic import ValidationError

    from service.settings import Settings

    with pytest.raises(ValidationError) as info:
        Settings(data_dir=tmp_path, database_url=url)
    (problem,) = info.value.errors()
    assert problem["loc"] == ("database_url",) and why in problem["msg"], problem
    assert "hunter2" not in str(info.value)


@pytest.mark.parametrize("url", [None, "", "sqlite:///elsewhere.db", "postgresql://:x@/"])
def test_database_urls_sqlalchemy_reads_are_accepted(tmp_path, url):
    """Whether the database answers is checked at start (service/startup.py); an empty URL
    is the default, SQLite in the data directory."""
    from service.settings import Settings

    settings = Settings(data_dir=tmp_path, database_url=url)
    default = f"sqlite:///{tmp_path / 'flycrane.db'}"
    assert settings.resolved_database_url == (url or default)
