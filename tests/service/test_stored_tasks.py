"""A stored task means what the user sent (issue 22, item 3): options left out stay left
out, so the worker that reads the task back decides as the CLI does."""

from __future__ import annotations

from flycrane.world.scene import load_scene
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec
from tests.service.conftest import running_service, wait_finished

#: A small tetrahedron 4 m beside the Rescue's path: a mesh scene, nothing in the way.
TETRAHEDRON = {
    "kind": "mesh",
    "vertices": [[6, 6, 0], [6.5, 6, 0], [6, 6.5, 0], [6, 6, 0.5]],
    "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
}


def test_a_mesh_scene_posted_without_a_planner_is_planned_as_the_cli_plans_it(tmp_path):
    rescue = load_scene("rescue")[0].model_dump(mode="json")
    scene = {**rescue, "obstacles": [*rescue["obstacles"], TETRAHEDRON]}
    sent = {
        "scene": scene,
        "planner": {"seed": 1, "time_budget": 60},
        "mission": {"position_error": "exact"},
    }
    as_the_cli = resolve_task(TaskSpec.model_validate(sent)).algorithm
    with running_service(tmp_path) as client:
        response = client.post("/v1/tasks", json=sent)
        assert response.status_code == 202, response.text
        task_id = response.json()["id"]
        task = wait_finished(client, task_id, timeout=240)
        stored = client.app.state.service.store.get(task_id).request  # what the worker read
    assert stored["planner"]["algorithm"] is None  # left to the scene, as sent
    assert task["status"] == "done", task.get("error")
    assert resolve_task(TaskSpec.model_validate(stored)).algorithm == as_the_cli
