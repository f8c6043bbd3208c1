"""The plan viewer through HTTP and in a real browser: the service run by uvicorn on
loopback, Debian's Chromium driven by Playwright, and the bundle's view.html from file://.

Evidence is independent of the viewer's code: positions come from the task's tracks.json,
limits from design.md's defaults, pixels from Chromium's own screenshots and canvases.
Every wait is for a condition, bounded in time. With FLYCRANE_SCREENSHOTS=<dir> the
screenshots are also kept there (docs/ holds the committed ones; README, "Plan viewer").
"""

from __future__ import annotations

import io
import json
import os
import shutil
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.service.conftest import wait_finished
from tests.service.live import CHROMIUM, browser_context, live_service, planned_task

#: design.md s.5 defaults, which the benchmark system (and so Rescue) uses.
F_LO, F_HI, H = 0.5, 30.0, 25.0
SLIDER_EPSILON = 1e-3  # [s]


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    with live_service(tmp_path_factory.mktemp("viewer")) as (client, data_dir):
        yield client, data_dir


@pytest.fixture(scope="module")
def rescue(service):
    client, data_dir = service
    task = planned_task(client, {"name": "rescue viewer", "planner": {"seed": 0}})
    tracks = client.get(f"/v1/tasks/{task['id']}/artifacts/tracks.json").json()
    return task, tracks, data_dir / "tasks" / task["id"]


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    if not CHROMIUM.exists():
        pytest.skip(
            f"no Chromium at {CHROMIUM}: `make test` installs Debian's chromium with apt-get "
            "where it can (as root or with passwordless sudo), and could not here"
        )
    with browser_context(tmp_path_factory.mktemp("chromium-profile")) as context:
        yield context


def test_view_json_is_the_document_of_the_task(service, rescue):
    client, _ = service
    task, tracks, _ = rescue
    document = client.get(f"/v1/tasks/{task['id']}/view.json").json()
    assert document["format"] == "flycrane.view/1" and document["title"] == "rescue viewer"
    frames = document["planned"]
    np.testing.assert_allclose(
        np.array(frames["drones"])[frames["waypoint_frames"]], tracks["drones_enu"], atol=2e-6
    )
    assert [o["name"] for o in document["scene"]["obstacles"]] == ["west building", "east building"]


def test_view_refuses_what_it_cannot_show(service, rescue):
    client, _ = service
    assert client.get("/v1/tasks/nope/view").status_code == 404
    # design.md's first Puzzle takes bitrrt tens of thousands of attempts, not 0.01 s
    too_short = {"name": "too short", "scene": "puzzle_first", "planner": {"time_budget": 0.01}}
    failed = client.post("/v1/tasks", json=too_short)
    task = wait_finished(client, failed.json()["id"])
    assert task["status"] == "failed"
    for suffix in ("view", "view.json"):
        refused = client.get(f"/v1/tasks/{task['id']}/{suffix}")
        assert refused.status_code == 409 and "not done" in refused.json()["detail"]


def test_static_files_only_the_viewers(service):
    client, _ = service
    script = client.get("/v1/viewer/static/viewer.js")
    assert script.status_code == 200 and "javascript" in script.headers["content-type"]
    assert client.get("/v1/viewer/static/vendor/three/LICENSE").status_code == 200
    for name in ("..%2Fdocument.py", "missing.js", "vendor%2F..%2F..%2Fpage.py"):
        assert client.get(f"/v1/viewer/static/{name}").status_code == 404, name


def wait_until(page, expression: str, timeout_s: float) -> None:
    """Poll ``expression`` in the page until it is true. Through ``evaluate``, which the
    pages' Content-Security-Policy allows: ``wait_for_function``'s predicate runs through
    eval in the page, which the policy forbids."""
    deadline = time.monotonic() + timeout_s
    while not page.evaluate(expression):
        assert time.monotonic() < deadline, f"{expression} not true within {timeout_s} s"
        time.sleep(0.05)


class Viewer:
    """A page of the viewer, with every console error and uncaught exception it raised."""

    def __init__(self, context, url: str) -> None:
        self.page = context.new_page()
        self.problems: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", self._console)
        self.page.on("pageerror", lambda e: self.problems.append(f"page error: {e}"))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.goto(url)
        wait_until(self.page, "window.flycraneViewer && window.flycraneViewer.ready", 60.0)

    def _console(self, message) -> None:
        if message.type == "error":
            self.problems.append(f"console error: {message.text} at {message.location}")

    def set_slider(self, t: float) -> None:
        """Move the slider (as a person does: an input event) to just after time t.

        Just after: the range input keeps 15 significant digits, which can fall below t and
        show the frame before; frames are tens of milliseconds apart, so t + 1 ms shows t's.
        """
        self.page.locator("#time").fill(str(float(t) + SLIDER_EPSILON))

    def canvas(self) -> np.ndarray:
        png = self.page.locator("#view canvas").screenshot()
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)

    def keep(self, name: str) -> None:
        """Save a screenshot of the whole page where FLYCRANE_SCREENSHOTS says."""
        folder = os.environ.get("FLYCRANE_SCREENSHOTS")
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
            self.page.screenshot(path=str(Path(folder) / name))

    def close(self) -> None:
        self.page.close()


def assert_not_blank(image: np.ndarray) -> None:
    """A rendered scene, not a cleared canvas: many colours, none covering nearly all."""
    colours, counts = np.unique(image.reshape(-1, 3), axis=0, return_counts=True)
    assert len(colours) > 200, f"only {len(colours)} colours"
    assert counts.max() < 0.8 * image.shape[0] * image.shape[1]


def test_view_renders_and_the_platform_follows_the_slider(service, rescue, browser):
    client, _ = service
    task, tracks, _ = rescue
    viewer = Viewer(browser, f"{client.base_url}v1/tasks/{task['id']}/view")
    try:
        before = viewer.canvas()
        assert_not_blank(before)
        q, drones, times = (np.array(tracks[k]) for k in ("configurations", "drones_enu", "time"))
        middle = len(times) // 2
        viewer.set_slider(times[middle])
        state = viewer.page.evaluate(
            "({t: flycraneViewer.time, p: flycraneViewer.platformPosition(),"
            " d: flycraneViewer.dronePositions()})"
        )
        assert state["t"] == pytest.approx(times[middle] + SLIDER_EPSILON)
        # At a waypoint's time the page shows that waypoint's platform and drones.
        np.testing.assert_allclose(state["p"], q[middle, :3], atol=1e-5)
        np.testing.assert_allclose(state["d"], drones[middle], atol=1e-5)
        assert np.linalg.norm(q[middle, :3] - q[0, :3]) > 1.0  # the load has moved...
        after = viewer.canvas()
        changed = np.any(np.abs(after - before) > 30, axis=-1).mean()
        assert changed > 0.002, f"{changed:.4%} of the pixels changed"  # ...and so has the view
        viewer.keep("viewer_rescue.png")
        assert viewer.problems == []
    finally:
        viewer.close()


def test_plots_draw_the_limits_and_the_cursor(service, rescue, browser):
    client, _ = service
    task, tracks, _ = rescue
    viewer = Viewer(browser, f"{client.base_url}v1/tasks/{task['id']}/view")
    try:
        viewer.set_slider(tracks["time"][3])
        drawn = viewer.page.evaluate(DRAWN_LIMITS)
        limits = {name: [(d["label"].split(" =")[0], d["value"]) for d in lines]
                  for name, lines in drawn.items()}  # fmt: skip
        assert limits == {"tension": [("f_lo", F_LO), ("f_hi", F_HI)], "thrust": [("h", H)]}
        for name, lines in drawn.items():
            for line in lines:
                # A dashed line (6 px on, 4 off): dark pixels along more than half its row.
                assert line["dark"] > 0.5, (name, line)
            assert drawn[name][0]["cursor"] > 0.5, name  # the time cursor's column
        assert viewer.problems == []
    finally:
        viewer.close()


#: For each plot: its limit series (label, value), the fraction of dark pixels on the row
#: where the value is drawn (best of three rows), and on the column of the time cursor.
DRAWN_LIMITS = """
(() => {
  const out = {};
  for (const [name, u] of Object.entries(flycraneViewer.plots)) {
    const {left, top, width, height} = u.bbox;
    const dark = (x, y, w, h) => {
      const d = u.ctx.getImageData(x, y, w, h).data;
      let n = 0;
      for (let i = 0; i < d.length; i += 4) {
        if (d[i + 3] > 0 && d[i] + d[i + 1] + d[i + 2] < 300) n++;
      }
      return n / (w * h);
    };
    const x = Math.round(u.valToPos(flycraneViewer.time, 'x', true));
    const cursor = Math.max(...[x - 1, x, x + 1].map((c) => dark(c, top, 1, height)));
    out[name] = u.series.slice(1).map((s, j) => ({s, j: j + 1}))
      .filter(({s}) => /^(f_lo|f_hi|h) =/.test(s.label))
      .map(({s, j}) => {
        const y = Math.round(u.valToPos(u.data[j][0], 'y', true));
        const rows = [y - 1, y, y + 1].map((r) => dark(left, r, width, 1));
        return {label: s.label, value: u.data[j][0], dark: Math.max(...rows), cursor};
      });
  }
  return out;
})()
"""


def test_play_runs_the_clock_and_pause_stops_it(service, rescue, browser):
    client, _ = service
    task, _, _ = rescue
    viewer = Viewer(browser, f"{client.base_url}v1/tasks/{task['id']}/view")
    try:
        viewer.page.locator("#play").click()
        wait_until(viewer.page, "flycraneViewer.time > 1.0", 30.0)
        viewer.page.locator("#play").click()
        assert viewer.page.evaluate("flycraneViewer.playing") is False
        stopped = viewer.page.evaluate("flycraneViewer.time")
        viewer.page.wait_for_timeout(300)  # paused: another frame must not move it
        assert viewer.page.evaluate("flycraneViewer.time") == stopped
        assert float(viewer.page.locator("#time").input_value()) == pytest.approx(stopped)
        assert viewer.problems == []
    finally:
        viewer.close()


def test_flown_track_and_reconstructed_platform_are_drawn(service, rescue, browser):
    """A flight report's flown.json (here: the plan shifted by d and 20 % late) is drawn;
    the reconstructed platform is the planned one shifted by d."""
    client, _ = service
    task, tracks, task_dir = rescue
    shift = np.array([0.4, 0.0, -0.3])
    flown_time = 1.2 * np.array(tracks["time"])
    flown = {
        "source": "sitl-true",
        "time": flown_time.tolist(),
        "drones_enu": (np.array(tracks["drones_enu"]) + shift).tolist(),
    }
    (task_dir / "flown.json").write_text(json.dumps(flown), encoding="utf-8")
    try:
        viewer = Viewer(browser, f"{client.base_url}v1/tasks/{task['id']}/view")
        k = len(flown_time) // 2
        viewer.set_slider(flown_time[k])
        state = viewer.page.evaluate(
            "({frames: flycraneViewer.frames(), visible: flycraneViewer.flownPlatformVisible(),"
            " p: flycraneViewer.flownPlatformPosition(),"
            " series: flycraneViewer.plots.tension.series.map((s) => s.label)})"
        )
        assert state["visible"] is True
        q = np.array(tracks["configurations"])
        np.testing.assert_allclose(state["p"], q[k, :3] + shift, atol=1e-4)
        assert "flown min t_lo" in state["series"]
        viewer.page.locator("#show-flown").uncheck()
        assert viewer.page.evaluate("flycraneViewer.flownPlatformVisible()") is False
        viewer.page.locator("#show-flown").check()
        viewer.keep("viewer_rescue_flown.png")
        assert viewer.problems == []
        viewer.close()
    finally:
        (task_dir / "flown.json").unlink()


def test_task_list_links_to_the_view(service, rescue, browser):
    client, _ = service
    task, _, _ = rescue
    viewer_page = browser.new_page()
    try:
        viewer_page.goto(f"{client.base_url}v1/viewer")
        row = viewer_page.locator("tr", has_text="rescue viewer")
        row.get_by_role("link", name="view").click()
        wait_until(viewer_page, "window.flycraneViewer && flycraneViewer.ready", 60.0)
        assert viewer_page.url.endswith(f"/v1/tasks/{task['id']}/view")
    finally:
        viewer_page.close()


def test_bundle_view_opens_offline_from_file(service, rescue, browser, tmp_path):
    client, _ = service
    task, tracks, _ = rescue
    bundle = zipfile.ZipFile(io.BytesIO(client.get(f"/v1/tasks/{task['id']}/bundle.zip").content))
    bundle.extractall(tmp_path)
    shutil.copy(tmp_path / "view.html", tmp_path / "moved.html")  # one file, nothing beside it
    viewer = Viewer(browser, (tmp_path / "moved.html").as_uri())
    try:
        assert_not_blank(viewer.canvas())
        viewer.set_slider(tracks["time"][-1])
        np.testing.assert_allclose(
            viewer.page.evaluate("flycraneViewer.platformPosition()"),
            tracks["configurations"][-1][:3],
            atol=1e-5,
        )
        # Nothing fetched from anywhere: the page and its inline data: modules only.
        assert all(u.startswith(("file:", "data:")) for u in viewer.requests), viewer.requests
        viewer.keep("viewer_offline.png")
        assert viewer.problems == []
    finally:
        viewer.close()
