"""Keeping the load safe around a drone that cannot keep its targets.

A drone whose attitude leaves what its own controller asks for (a weak motor, a broken
propeller: :attr:`~.team.FaultKind.ATTITUDE`) stops the team, or weakens while the team
holds after another fault, but it cannot stop where it is told: with a weak motor its
attitude lags its controller's for seconds, though its motors have thrust to spare, and it
swings away from its stop before it comes back. Braked at their own stops, the other two
let the cables go slack or the platform tilt past its bound (BENCHMARKS.md "A weak motor",
"A weak motor during a hold", "Which motor weakens").

Where the ground flies the drones (the stream executor) it moves the other two with it,
as little as keeps the load safe with room to spare: every :data:`ROOM_PERIOD_S` the
faulty drone's deviation from its target is carried :data:`PREDICTION_S` ahead with its
velocity and the acceleration its lean gives it, and the others' targets move by the
least fraction of it (0, 1/4, ... 1; :class:`FormationRoom`) at which the load, rebuilt by
the direct kinematics with the faulty drone off by the whole deviation, is feasible with
every statics margin at least :data:`ROOM_MARGIN_N` (or the plan's own there, if less) and
keeps the plan's clearance from the real obstacles; where no fraction keeps that margin,
the feasible and clear one with the largest; where none is feasible, the largest at which
the formation, translated as a whole, keeps that clearance. The faulty drone's velocity and
lean acceleration, beyond its target's, are fed forward by the same fraction: the others
start moving with it before its deviation shows.

Moving them by the whole deviation always (tried first) kept the Puzzle's load but took
healthy drones into the Rescue's buildings. Beyond :data:`LIMIT` the drone is not swinging
but leaving (falling, flying away), and the others move no farther. The players on board
fly their own trajectories: there the team brakes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.robust_statics import margins
from flycrane.model.statics import evaluate_statics
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import ValidityChecker
from missions.autopilots.location import VehicleFrame
from missions.execution.vehicles import VehicleState
from missions.geodesy import enu_from_ned
from missions.task.spec import TaskSpec
from missions.trajectory.drone_trajectory import DroneTrajectory

#: The farthest [m] the healthy drones follow a faulty one from their targets.
LIMIT = 1.0
#: The fractions of the shift tried, largest first.
FRACTIONS = (1.0, 0.75, 0.5, 0.25)
#: How often the room is checked [s of common time]: a check takes about a millisecond,
#: and the executor asks for the shift four times a tick.
ROOM_PERIOD_S = 0.1
#: How far ahead [s] the faulty drone's deviation is carried on with its velocity for the
#: check: about what the others' controllers take to follow a target, and the check's
#: period.
PREDICTION_S = 0.5
#: The least statics margin [N] (slack, overload, thrust) the others keep the load at
#: while they follow (the plan's own where it has less).
ROOM_MARGIN_N = 0.5

#: The horizontal components of an ENU vector (the lean gives no vertical acceleration).
HORIZONTAL = np.array([1.0, 1.0, 0.0])

Target = Callable[[float], tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]


@dataclass(frozen=True)
class FormationRoom:
    """How far the others follow a faulty drone's deviation (module docstring)."""

    system: CableSystem
    trajectory: DroneTrajectory
    checker: ValidityChecker  #: the real obstacles grown by the plan's clearance

    @classmethod
    def of_task(
        cls, task: TaskSpec, base_dir: Path, trajectory: DroneTrajectory, clearance: float
    ) -> FormationRoom:
        """From a task's directory's (self-contained) task: its scene's real obstacles
        grown by ``clearance`` [m]."""
        problem = PlanningProblem.from_scene(task.scene, task.system, base_dir)  # type: ignore[arg-type]
        room = cls(problem.system, trajectory, problem.validity.with_clearance(clearance))
        room(0.0, np.zeros(3), 0)  # the first check loads the compiled checker: not in flight
        return room

    def __call__(self, tau: float, shift: NDArray[np.float64], weak: int) -> float:
        """How much of ``shift`` [m, ENU], drone ``weak``'s (0-based) deviation, the other
        two follow at plan time ``tau`` (module docstring): the least of :data:`FRACTIONS`
        and 0 at which the load is safe (feasible and clear) with drone ``weak`` off by the
        whole shift and keeps :data:`ROOM_MARGIN_N`; where none keeps it, the safe one
        with the largest margin; where none is safe, the largest at which the formation
        translated as a whole is clear; 0 if none is."""
        drones = self.trajectory.in_task_frame(self.trajectory.at(tau)[0])
        q = configuration_from_drone_positions(self.system, drones).q
        fractions = (0.0, *FRACTIONS[::-1])
        moved = drones + np.multiply.outer(fractions, shift)[:, None, :]
        moved[:, weak] = drones[weak] + shift
        solved = configuration_from_drone_positions(
            self.system, moved, np.repeat(q, len(fractions), axis=0)
        )
        safe = solved.converged & self.checker.is_safe(solved.q)
        if safe.any():
            least = margins(evaluate_statics(self.system, np.vstack([q, solved.q]))).min(axis=1)
            kept = np.where(safe, least[1:], -np.inf)
            enough = kept >= min(ROOM_MARGIN_N, float(least[0]))
            return fractions[int(np.argmax(enough) if enough.any() else np.argmax(kept))]
        translated = np.repeat(q, len(FRACTIONS), axis=0)
        translated[:, :3] += np.outer(FRACTIONS, shift)
        clear = self.checker.is_safe(translated)
        return next((f for f, ok in zip(FRACTIONS, clear, strict=True) if ok), 0.0)


@dataclass
class Anchor:
    """The faulty drone the other two follow (module docstring)."""

    vehicle: VehicleState
    frame: VehicleFrame
    home: NDArray[np.float64]  #: its home in the task frame (ENU)
    target: Target  #: its target (home-relative ENU position, velocity, acceleration) at t
    tau: Callable[[float], float]  #: the plan time at common time t
    drone: int  #: which (0-based)
    room: FormationRoom | None  #: None: no obstacles to keep clear of
    #: (common time, fraction) of the last room check
    checked: tuple[float, float] = (-float("inf"), 0.0)

    def shift(self, t: float) -> tuple[NDArray, NDArray, NDArray]:
        """(position, velocity, acceleration) the others' targets move by at common time
        ``t`` (ENU)."""
        estimate, velocity = self.vehicle.estimate(), self.vehicle.velocity_estimate()
        lean = self.vehicle.lean_acceleration()
        if estimate is None or velocity is None or lean is None:
            return np.zeros(3), np.zeros(3), np.zeros(3)
        at, ned = estimate
        p, v, a = self.target(at)
        drift = enu_from_ned(velocity) - v
        push = enu_from_ned(lean) - a * HORIZONTAL
        deviation = self.frame.task_position(ned) - (p + self.home) + drift * (t - at)
        length = float(np.linalg.norm(deviation))
        if length > LIMIT:
            deviation, drift, push = deviation * (LIMIT / length), np.zeros(3), np.zeros(3)
        fraction = self._fraction(t, deviation, drift, push)
        return deviation * fraction, drift * fraction, push * fraction

    def _fraction(
        self,
        t: float,
        deviation: NDArray[np.float64],
        drift: NDArray[np.float64],
        push: NDArray[np.float64],
    ) -> float:
        """The room's fraction for the deviation :data:`PREDICTION_S` ahead, checked every
        :data:`ROOM_PERIOD_S`."""
        if self.room is None:
            return 1.0
        if t - self.checked[0] >= ROOM_PERIOD_S:
            ahead = deviation + drift * PREDICTION_S + push * (PREDICTION_S**2 / 2.0)
            ahead *= min(1.0, LIMIT / max(float(np.linalg.norm(ahead)), 1e-9))
            self.checked = (t, self.room(self.tau(t), ahead, self.drone))
        return self.checked[1]
