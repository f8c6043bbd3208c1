"""What the files of a task's directory hold, as typed models: ``summary.json``
(:class:`TaskOutcome`, with its :class:`MissionSummary` and :class:`Release`) and
``tracks.json`` (:class:`Tracks`). :class:`~missions.task.directory.TaskDirectory` writes and
reads them; their readers refuse what this version does not write (an edited file)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from flycrane.planning.metrics import PathMetrics
from missions.autopilots.spline import SpeedLimits
from missions.position_error import PositionErrorModel
from missions.trajectory.flight_plan import SetDown
from missions.trajectory.motion import DroneMotion
from missions.trajectory.timing_tolerance import TimingTolerance
from missions.trajectory.vertical_legs import VerticalLeg

#: The drones of a task, 1-based.
DRONES = (1, 2, 3)
#: The rate the modelled motions are stored at in tracks.json [Hz]: read by interpolation,
#: they stay within about a millimetre of the mission model's 100 Hz samples
#: (BENCHMARKS.md "Bounded work"), at a fifth of the size.
STORED_MOTION_RATE_HZ = 20.0

Status = Literal["done", "failed", "cancelled"]


@dataclass(frozen=True)
class Release:
    """Where each drone holds before the release (NAV_LOITER_UNLIM) and the item the
    release jumps to (:mod:`missions.export.builder`)."""

    hold_seq: int
    release_seq: int


@dataclass(frozen=True)
class MissionSummary:
    """What the missions of a task are: summary.json's ``mission``."""

    waypoints: int
    duration: float  #: release to the end of the last leg [s]
    max_platform_deviation: float  #: [m] along the modelled targets
    max_cable_length_error: float  #: [m]
    max_tracking_deviation: float  #: [m] along the modelled vehicles
    timing_tolerance: TimingTolerance
    early_legs: tuple[tuple[int, int], ...]  #: (drone, leg), 1-based
    items_per_drone: tuple[int, ...]
    release: Release
    obstacle_clearance: float  #: [m] kept by the plan
    position_error: PositionErrorModel
    lift_off: VerticalLeg | None
    set_down: SetDown | None
    #: [N] the path's least statics margin less what the drones' own errors can take of
    #: it (:mod:`flycrane.model.robust_statics`), and which margin that is (None in a
    #: summary written before they were measured)
    robust_statics_margin: float | None = None
    robust_statics_limit: str | None = None
    #: [m] the path's least gap less what the drones' errors can close there, where the
    #: task asked for it (``mission.robust_clearance``)
    robust_margin: float | None = None

    def as_dict(self) -> dict[str, Any]:
        robust = {
            name: value
            for name, value in (
                ("robust_statics_margin", self.robust_statics_margin),
                ("robust_statics_limit", self.robust_statics_limit),
                ("robust_margin", self.robust_margin),
            )
            if value is not None
        }
        return {
            "waypoints": self.waypoints,
            "duration": self.duration,
            "max_platform_deviation": self.max_platform_deviation,
            "max_cable_length_error": self.max_cable_length_error,
            "max_tracking_deviation": self.max_tracking_deviation,
            "timing_tolerance": self.timing_tolerance.as_dict(),
            "early_legs": [list(e) for e in self.early_legs],
            "items_per_drone": list(self.items_per_drone),
            "release": asdict(self.release),
            "obstacle_clearance": self.obstacle_clearance,
            "position_error": self.position_error.model_dump(),
            "lift_off": self.lift_off.as_dict() if self.lift_off else None,
            "set_down": self.set_down.as_dict() if self.set_down else None,
            **robust,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MissionSummary:
        return cls(
            waypoints=int(data["waypoints"]),
            duration=float(data["duration"]),
            max_platform_deviation=float(data["max_platform_deviation"]),
            max_cable_length_error=float(data["max_cable_length_error"]),
            max_tracking_deviation=float(data["max_tracking_deviation"]),
            timing_tolerance=TimingTolerance(**data["timing_tolerance"]),
            early_legs=tuple((int(d), int(k)) for d, k in data["early_legs"]),
            items_per_drone=tuple(int(n) for n in data["items_per_drone"]),
            release=Release(**data["release"]),
            obstacle_clearance=float(data["obstacle_clearance"]),
            position_error=PositionErrorModel.model_validate(data["position_error"]),
            lift_off=VerticalLeg.from_dict(data["lift_off"]) if data["lift_off"] else None,
            set_down=SetDown.from_dict(data["set_down"]) if data["set_down"] else None,
            robust_statics_margin=data.get("robust_statics_margin"),
            robust_statics_limit=data.get("robust_statics_limit"),
            robust_margin=data.get("robust_margin"),
        )


def raised_clearance(attempt: dict[str, Any]) -> bool:
    """Whether an entry of :attr:`TaskOutcome.attempts` was a path planned again with more
    clearance (``mission.robust_clearance``; it names the clearance), not one whose
    missions failed their check."""
    return "clearance" in attempt


@dataclass(frozen=True)
class TaskOutcome:
    """What a task's run produced (summary.json; the service stores it as the task's
    result). ``artifacts`` maps names to files relative to the directory."""

    status: Status
    reason: str = ""
    planner_status: str = ""
    planner_statistics: dict[str, Any] = field(default_factory=dict)
    metrics: PathMetrics | None = None
    mission: MissionSummary | None = None
    artifacts: dict[str, str] = field(default_factory=dict)
    #: paths planned before the last: seed and reason; whose missions failed their check,
    #: or too close for the drones' errors (:func:`raised_clearance`)
    attempts: tuple[dict[str, Any], ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "status": self.status,
            "reason": self.reason,
            "planner_status": self.planner_status,
            "planner_statistics": dict(self.planner_statistics),
            "metrics": self.metrics.as_dict() if self.metrics else None,
            "mission": self.mission.as_dict() if self.mission else None,
            "artifacts": dict(self.artifacts),
            "attempts": [dict(a) for a in self.attempts],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TaskOutcome:
        return cls(
            status=data["status"],
            reason=data.get("reason", ""),
            planner_status=data.get("planner_status", ""),
            planner_statistics=dict(data.get("planner_statistics") or {}),
            metrics=PathMetrics(**data["metrics"]) if data.get("metrics") else None,
            mission=MissionSummary.from_dict(data["mission"]) if data.get("mission") else None,
            artifacts=dict(data.get("artifacts") or {}),
            attempts=tuple(data.get("attempts") or ()),
        )


@dataclass(frozen=True)
class Tracks:
    """tracks.json: the timed waypoints and everything the flight will be judged against.

    Waypoint arrays have W rows; the dense plan (``dense_time``, ``dense_configurations``)
    is the planned path on mission time, sampled as finely as the checks sampled it; the
    modelled motions are stored at :data:`STORED_MOTION_RATE_HZ`."""

    time: NDArray[np.float64]  #: (W,) mission time of each waypoint [s from the release]
    configurations: NDArray[np.float64]  #: (W, 9)
    drones_enu: NDArray[np.float64]  #: (W, 3, 3) the planned drones [m]
    drones_stored_enu: NDArray[np.float64]  #: (W, 3, 3) as ArduPilot stores the waypoints
    drones_wgs84: NDArray[np.float64]  #: (W, 3, 3) latitude, longitude [deg], AMSL [m]
    speed_limits: tuple[tuple[SpeedLimits, ...], ...]  #: [drone][leg]
    annotations: tuple[dict[str, Any], ...]  #: per waypoint (:mod:`.annotations` records)
    timing_tolerance: TimingTolerance
    dense_time: NDArray[np.float64]  #: (N,) [s]
    dense_configurations: NDArray[np.float64]  #: (N, 9)
    motion: DroneMotion  #: the autopilots' targets as the mission model flies them
    vehicle_motion: DroneMotion  #: the modelled vehicles following those targets
    lift_off: VerticalLeg | None
    set_down: SetDown | None

    def as_dict(self) -> dict[str, Any]:
        return {
            "time": self.time.tolist(),
            "configurations": self.configurations.tolist(),
            "drones_enu": self.drones_enu.tolist(),
            "drones_stored_enu": self.drones_stored_enu.tolist(),
            "drones_wgs84": self.drones_wgs84.tolist(),
            "speed_limits": [[asdict(limit) for limit in row] for row in self.speed_limits],
            "annotations": list(self.annotations),
            "timing_tolerance": self.timing_tolerance.as_dict(),
            "dense": {
                "time": self.dense_time.tolist(),
                "configurations": self.dense_configurations.tolist(),
            },
            "motion": self.motion.decimated(STORED_MOTION_RATE_HZ).as_dict(),
            "vehicle_motion": self.vehicle_motion.decimated(STORED_MOTION_RATE_HZ).as_dict(),
            "lift_off": self.lift_off.as_dict() if self.lift_off else None,
            "set_down": self.set_down.as_dict() if self.set_down else None,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Tracks:
        """Raises ValueError where the arrays' shapes do not fit together (an edited file)."""
        tracks = cls(
            time=np.array(data["time"], dtype=float),
            configurations=np.array(data["configurations"], dtype=float),
            drones_enu=np.array(data["drones_enu"], dtype=float),
            drones_stored_enu=np.array(data["drones_stored_enu"], dtype=float),
            drones_wgs84=np.array(data["drones_wgs84"], dtype=float),
            speed_limits=tuple(
                tuple(SpeedLimits(**limit) for limit in row) for row in data["speed_limits"]
            ),
            annotations=tuple(data["annotations"]),
            timing_tolerance=TimingTolerance(**data["timing_tolerance"]),
            dense_time=np.array(data["dense"]["time"], dtype=float),
            dense_configurations=np.array(data["dense"]["configurations"], dtype=float),
            motion=DroneMotion.from_dict(data["motion"]),
            vehicle_motion=DroneMotion.from_dict(data["vehicle_motion"]),
            lift_off=VerticalLeg.from_dict(data["lift_off"]) if data["lift_off"] else None,
            set_down=SetDown.from_dict(data["set_down"]) if data["set_down"] else None,
        )
        tracks._check_shapes()
        return tracks

    def _check_shapes(self) -> None:
        w, n = len(self.time), len(self.dense_time)
        shapes: dict[str, tuple[NDArray[np.float64], tuple[int, ...]]] = {
            "time": (self.time, (w,)),
            "configurations": (self.configurations, (w, 9)),
            "drones_enu": (self.drones_enu, (w, 3, 3)),
            "drones_stored_enu": (self.drones_stored_enu, (w, 3, 3)),
            "drones_wgs84": (self.drones_wgs84, (w, 3, 3)),
            "dense.time": (self.dense_time, (n,)),
            "dense.configurations": (self.dense_configurations, (n, 9)),
        }
        for name, motion in (("motion", self.motion), ("vehicle_motion", self.vehicle_motion)):
            m = len(motion.time)
            shapes[f"{name}.time"] = (motion.time, (m,))
            shapes[f"{name}.drones_enu"] = (motion.drones, (m, 3, 3))
        for name, (array, shape) in shapes.items():
            if len(array) < 2:
                raise ValueError(f"{name} has {len(array)} rows, fewer than 2")
            if array.shape != shape:
                raise ValueError(f"{name} has shape {array.shape}, not {shape}")
            if not np.all(np.isfinite(array)):
                raise ValueError(f"{name} holds a value that is not a finite number")
        for name, time in (("time", self.time), ("dense.time", self.dense_time),
                           ("motion.time", self.motion.time),
                           ("vehicle_motion.time", self.vehicle_motion.time)):  # fmt: skip
            if np.any(np.diff(time) < 0):
                raise ValueError(f"{name} decreases")
        if len(self.speed_limits) != len(DRONES):
            raise ValueError(f"speed_limits has {len(self.speed_limits)} rows, not {len(DRONES)}")
