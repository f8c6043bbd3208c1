"""A task recorded done with hand-made missions, for the tests that need a done task but not
its planning: uploads to mock vehicles, artifacts and their headers."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from missions.export.formats import dumps, mission_json
from missions.export.items import DroneMission
from missions.export.parameter_file import parameter_file_text
from missions.task.directory import mission_file
from missions.task.documents import DRONES
from service.deps import ServiceState
from service.storage import TaskStatus


def done_task(
    state: ServiceState,
    missions: Sequence[DroneMission],
    parameters: Sequence[Mapping[str, float]],
    name: str = "fabricated",
) -> str:
    """Store a task that reads ``done``, whose artifacts are ``droneK.mission.json`` and
    ``droneK.parm`` of the missions and parameters given (drone 1 first); its id."""
    record = state.store.create({"name": name})
    folder = state.jobs.task_dir(record.id)
    folder.mkdir(parents=True)
    artifacts = {}
    for k, mission, values in zip(DRONES, missions, parameters, strict=True):
        for suffix, text in (
            ("mission.json", dumps(mission_json(mission))),
            ("parm", parameter_file_text(values, {})),
        ):
            name_k = mission_file(k, suffix)
            (folder / name_k).write_text(text, encoding="utf-8")
            artifacts[name_k] = name_k
    state.store.finish(record.id, record.attempt, TaskStatus.DONE, {"artifacts": artifacts}, None)
    return record.id
