"""Issue 22, item 12: what a browser may do with what the service sends.

- every response says ``nosniff``, may not be framed, and carries a Content-Security-Policy;
  a JSON artifact's lets nothing load or run, an HTML page's only this server's scripts
  (and its own inline ones by hash);
- ``/docs`` loads Swagger UI from this server (vendored), never from a CDN, and works under
  its policy in a real browser; ``FLYCRANE_API_DOCS=false`` switches the docs off;
- what carries no task data is open with a token set: the docs, ``/openapi.json`` and the
  viewer's static files alike (they answered 401 while the docs were open).
"""

from __future__ import annotations

import base64
import hashlib
import re

import pytest

from service.settings import Settings
from tests.missions.loopback import waypoint_mission
from tests.service.conftest import TEST_HOST, running_service
from tests.service.fabricated import done_task
from tests.service.live import CHROMIUM, browser_context, live_service

TOKEN = "a-long-enough-token-0123"
#: The directives every policy of ours has: nothing may frame the page, no <base>, no form.
FRAMING = ("frame-ancestors 'none'", "base-uri 'none'", "form-action 'none'")
_SCRIPT = re.compile(r"<script(?P<attributes>[^>]*)>(?P<body>.*?)</script>", re.DOTALL)
_LOADED = re.compile(r"""<(?:script|link)\b[^>]*?\b(?:src|href)="(?P<url>[^"]*)\"""")


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("headers")) as c:
        yield c


@pytest.fixture(scope="module")
def task(client):
    missions = [waypoint_mission(k, 2) for k in (1, 2, 3)]
    return done_task(client.app.state.service, missions, [{"WPNAV_ACCEL": 200.0}] * 3)


def policy(response) -> dict[str, str]:
    """The Content-Security-Policy header as {directive: sources}."""
    text = response.headers["content-security-policy"]
    pairs = (part.strip().partition(" ") for part in text.split(";") if part.strip())
    return {name: sources for name, _, sources in pairs}


def assert_hardened(response) -> dict[str, str]:
    assert response.headers["x-content-type-options"] == "nosniff"
    assert response.headers["x-frame-options"] == "DENY"
    directives = policy(response)
    for directive in FRAMING:
        name, _, sources = directive.partition(" ")
        assert directives[name] == sources, directives
    return directives


def test_every_kind_of_response_is_hardened(client, task):
    for path in (
        f"/v1/tasks/{task}",
        f"/v1/tasks/{task}/artifacts/drone1.mission.json",
        f"/v1/tasks/{task}/artifacts/drone1.parm",
        "/v1/tasks/nope",  # an error
        "/healthz",
        "/openapi.json",
    ):
        response = client.get(path)
        assert response.status_code in (200, 404), path
        assert assert_hardened(response)["default-src"] == "'none'", path
    # answered before any route: a wrong Host header, an oversized body
    assert_hardened(client.get("/healthz", headers={"host": "evil.example"}))
    assert_hardened(client.post("/v1/tasks", content=b"x" * 2_000_000))


def test_html_pages_run_only_this_servers_scripts_and_their_own(client, task):
    for path in ("/v1/viewer", "/docs"):
        response = client.get(path)
        assert response.status_code == 200 and response.headers["content-type"].startswith(
            "text/html"
        ), path
        directives = assert_hardened(response)
        assert directives["default-src"] == "'none'"
        sources = directives["script-src"].split()
        assert "'unsafe-inline'" not in sources and "'unsafe-eval'" not in sources
        for match in _SCRIPT.finditer(response.text):  # inline scripts only by their hash
            if "src=" in match["attributes"] or "application/json" in match["attributes"]:
                continue
            digest = hashlib.sha256(match["body"].encode()).digest()
            assert f"'sha256-{base64.b64encode(digest).decode()}'" in sources, path
        loaded_urls = [u for u in _LOADED.findall(response.text) if u != "data:,"]  # no icon
        assert loaded_urls, path
        for url in loaded_urls:  # every file from this server
            assert "//" not in url and not url.startswith("/"), (path, url)
            loaded = client.get(response.url.join(url))
            assert loaded.status_code == 200, (path, url)


def test_the_docs_come_from_this_server_with_their_license(client):
    page = client.get("/docs").text
    assert "cdn" not in page.lower() and "https://" not in page
    for name in ("swagger-ui/LICENSE", "swagger-ui/NOTICE", "swagger-ui/README.md"):
        assert client.get(f"/docs/static/{name}").status_code == 200, name
    readme = client.get("/docs/static/swagger-ui/README.md").text
    assert "swagger-ui-dist" in readme and "Apache-2.0" in readme
    for name in ("..%2Fsettings.py", "missing.js", "swagger-ui%2F..%2F..%2Fapp.py"):
        assert client.get(f"/docs/static/{name}").status_code == 404, name


def test_docs_and_viewer_files_are_open_and_tasks_are_not(tmp_path):
    with running_service(tmp_path, api_token=TOKEN) as client:
        for path in (
            "/docs",
            "/openapi.json",
            "/docs/static/swagger-ui/swagger-ui-bundle.js",
            "/v1/viewer/static/viewer.js",
            "/v1/viewer/static/vendor/three/LICENSE",
        ):
            assert client.get(path).status_code == 200, path
        for path in ("/v1/viewer", "/v1/tasks"):
            assert client.get(path).status_code == 401, path


def test_the_docs_can_be_switched_off(tmp_path):
    with running_service(tmp_path, api_docs=False) as client:
        for path in ("/docs", "/openapi.json", "/redoc", "/docs/static/swagger-ui/LICENSE"):
            assert client.get(path).status_code == 404, path
        assert client.get("/healthz").status_code == 200


def test_settings_say_the_docs_are_on_by_default():
    assert Settings(allowed_hosts=(TEST_HOST,)).api_docs is True


def test_the_docs_render_in_a_browser_under_their_policy(tmp_path):
    """Chromium opens /docs: Swagger UI lists the operations, the console holds no error (a
    policy violation is one), and no request leaves the server."""
    if not CHROMIUM.exists():
        pytest.skip(f"no Chromium at {CHROMIUM} (make test installs Debian's chromium)")
    (tmp_path / "data").mkdir()
    with (
        live_service(tmp_path / "data") as (client, _),
        browser_context(tmp_path / "profile") as context,
    ):
        page = context.new_page()
        problems: list[str] = []
        requests: list[str] = []
        page.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: problems.append(str(e)))
        page.on("request", lambda r: requests.append(r.url))
        page.goto(str(client.base_url.join("docs")))
        page.wait_for_selector("#operations-tasks-create_task_v1_tasks_post", timeout=60_000)
        assert problems == []
        base = str(client.base_url)
        assert requests and all(url.startswith(base) for url in requests), requests
        page.close()
