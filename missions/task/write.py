"""The writing phase of a task: its tracks, each drone's mission files, the MCAP log and
the profile plot, into the task's directory."""

from __future__ import annotations

from datetime import UTC, datetime

from flycrane.analysis.profiles import path_profile, plot_path_profile
from flycrane.planning.planners import PlanningOutcome
from missions.autopilots.ardupilot import team_parameters
from missions.export.formats import mission_files
from missions.export.mission_mcap import LogInputs, write_mcap
from missions.export.parameter_file import parameter_file_text
from missions.export.trajectory_file import trajectory_text
from missions.task.build import BuiltMissions
from missions.task.directory import MCAP_FILE, PROFILE_FILE, TaskDirectory, mission_file
from missions.task.limits import PhaseLimits
from missions.task.resolve import ResolvedTask

#: The head of every exported ``.parm`` file.
PARM_HEADER = """FlyCrane: parameters every drone of this mission must have (ArduCopter 4.5).
Load them before the flight; the upload reads them back and reports any that differ.
Never change BARO_GND_TEMP on a powered vehicle: its altitude estimate jumps."""


def write_files(
    directory: TaskDirectory,
    resolved: ResolvedTask,
    planned: PlanningOutcome,
    built: BuiltMissions,
    limits: PhaseLimits | None = None,
) -> None:
    """The writing phase: tracks, each drone's mission files, the MCAP log, the plot;
    ``limits`` are checked between them.

    Raises
    ------
    Cancelled, MissionFailure
        A cancel, or past the deadline (:class:`~missions.task.limits.PhaseLimits`).
    """
    given = limits or PhaseLimits()

    def check() -> None:
        given.check("its files were written")

    task, problem = resolved.task, resolved.problem
    options, system = task.mission, problem.system
    settings = built.flight.settings
    team, why = team_parameters(resolved.position_error.height_source)
    parameters, reasons = {**settings.parameters(), **team}, {**settings.reasons(), **why}
    parm = parameter_file_text(parameters, reasons, PARM_HEADER)
    files: dict[str, str] = {}
    for mission in built.missions:
        texts = {**mission_files(mission, options.max_drone_speed), "parm": parm}
        texts["trajectory.csv"] = trajectory_text(
            built.trajectory, mission.drone, options.origin, task.name
        )
        files.update({mission_file(mission.drone, s): text for s, text in texts.items()})
    directory.write_tracks(built.tracks)
    for name, text in files.items():
        directory.write_text(name, text)
    check()
    start = options.start_time_utc or datetime.now(UTC)
    result = planned.result
    write_mcap(
        directory.file(MCAP_FILE),
        LogInputs(
            system=system,
            scene=problem.scene,
            track=built.track,
            annotations=built.annotations,
            missions=list(built.missions),
            options=options,
            start_ns=int(start.timestamp() * 1e9),
            metadata={
                "system": system.spec.model_dump(mode="json"),
                "scene": problem.scene.model_dump(mode="json"),
                "planner": {
                    "planner_status": result.status.value,
                    "planner_statistics": {
                        **result.statistics.as_dict(),
                        "smoothing_time": planned.smoothing_time,
                    },
                },
                "mission": built.summary.as_dict(),
            },
        ),
    )
    directory.record(MCAP_FILE, "mcap")
    check()
    profile = path_profile(system, problem.space, planned.path)
    plot_path_profile(
        profile,
        system,
        directory.file(PROFILE_FILE),
        title=f"{task.name or problem.scene.name}: tensions and thrusts",
    )
    directory.record(PROFILE_FILE, "profile")
