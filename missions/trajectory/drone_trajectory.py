"""The plan's time law as each drone's trajectory: position, velocity and acceleration
against plan time, for executors that play it from one clock (:mod:`missions.execution`).

The dense plan (the planned path on its quasi-static time law,
:mod:`missions.trajectory.time_law`, with every drone's turns at the path's corners within the
acceleration limit too: a drone that flies its velocity and acceleration, unlike one that
rounds waypoints, has to slow down there), followed by the set-down's slow vertical leg if
the task has one, is sampled every :data:`SAMPLE_STEP_S`. Positions are the plan's own (linear
between the dense samples, a few centimetres apart), so the load's safety is the plan's;
velocity and acceleration are the first and second derivatives of a local cubic fit over
:data:`DERIVATIVE_WINDOW_S` (Savitzky-Golay, scipy.signal), the feed-forward a copter's
position controller needs not to lag its target; at the ends the fit spans the holds
before the release and after the arrival. Between samples a trajectory is read by
cubic Hermite interpolation of position and velocity (:meth:`DroneTrajectory.at`).

Frame: ENU metres relative to each drone's *home*, the point ``home_height`` above the
ground below its start, where ArduPilot sets home at arming and relative altitudes count
from (the missions' frame, :class:`~missions.options.MissionOptions`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from flycrane.model.kinematics import matrix_from_tilt_torsion
from missions.options import MissionOptions
from missions.trajectory.time_law import time_law, vertical_profile
from missions.trajectory.tracks import Track
from missions.trajectory.vertical_legs import VerticalLeg

#: Most time between the trajectory's samples [s] (20 Hz; an executor interpolates between;
#: the step is made to end on the plan's end).
SAMPLE_STEP_S = 0.05
#: Span of the local cubic fit that gives velocity and acceleration [s]: long enough that a
#: corner of the path (a direction change within one dense segment) does not become an
#: acceleration spike, short enough to follow the time law's 0.25 m/s^2 ramps.
DERIVATIVE_WINDOW_S = 0.45


@dataclass(frozen=True)
class DroneTrajectory:
    """Three drones' positions, velocities and accelerations on plan time (ENU, each drone
    relative to its home; module docstring)."""

    time: NDArray[np.float64]  #: (N,) plan time from the release [s], uniform step
    position: NDArray[np.float64]  #: (N, 3, 3) [drone, ENU] [m]
    velocity: NDArray[np.float64]  #: (N, 3, 3) [m/s]
    acceleration: NDArray[np.float64]  #: (N, 3, 3) [m/s^2]
    homes: NDArray[np.float64]  #: (3, 3) each drone's home in the task's ENU frame [m]
    #: plan time the set-down's descent starts at [s] (None: no set-down)
    set_down_start: float | None = None

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    @property
    def step(self) -> float:
        return float(self.time[1] - self.time[0])

    def at(self, tau: NDArray[np.float64] | float) -> tuple[NDArray, NDArray, NDArray]:
        """Position, velocity and acceleration at plan times ``tau`` (clamped to the
        trajectory), each (..., 3 drones, 3): cubic Hermite in position and velocity,
        acceleration linear between samples."""
        tau = np.asarray(np.clip(np.asarray(tau, dtype=float), 0.0, self.duration))
        k = np.clip(np.floor(tau / self.step).astype(np.int64), 0, len(self.time) - 2)
        h = self.step
        s = ((tau - self.time[k]) / h)[..., None, None]
        p0, p1 = self.position[k], self.position[k + 1]
        v0, v1 = self.velocity[k], self.velocity[k + 1]
        s2, s3 = s * s, s * s * s
        position = (
            (2 * s3 - 3 * s2 + 1) * p0
            + (s3 - 2 * s2 + s) * h * v0
            + (-2 * s3 + 3 * s2) * p1
            + (s3 - s2) * h * v1
        )
        velocity = (
            (6 * s2 - 6 * s) * p0 / h
            + (3 * s2 - 4 * s + 1) * v0
            + (-6 * s2 + 6 * s) * p1 / h
            + (3 * s2 - 2 * s) * v1
        )
        acceleration = (1 - s) * self.acceleration[k] + s * self.acceleration[k + 1]
        return position, velocity, acceleration

    def nearest_time(
        self, k: int, position: NDArray[np.float64], tau: float, window: float
    ) -> float:
        """The plan time within ``window`` [s] of ``tau`` (on a 0.02 s grid) at which drone
        k is nearest ``position`` (task frame): how far along its plan a drone is."""
        times = np.clip(tau + np.arange(-window, window, 0.02), 0.0, self.duration)
        planned = self.at(times)[0][:, k] + self.homes[k]
        return float(times[np.argmin(np.linalg.norm(planned - position, axis=-1))])

    def in_task_frame(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        """Home-relative positions of the three drones (..., 3, 3) in the task's ENU frame
        (one drone's: add its row of :attr:`homes`)."""
        return position + self.homes

    @classmethod
    def of_plan(
        cls,
        track: Track,
        options: MissionOptions,
        set_down: VerticalLeg | None = None,
        step: float = SAMPLE_STEP_S,
    ) -> DroneTrajectory:
        """The trajectory of a dense plan (its drones on its time law), and of the set-down
        leg after it (``set_down.height`` down at ``options.vertical_leg_speed``, speeding
        up and braking at ``options.max_acceleration``)."""
        drones = track.drones
        rotations = matrix_from_tilt_torsion(track.q[:, 3:6])
        time = time_law(drones, rotations, options, corners=True)
        set_down_start = float(time[-1]) if set_down is not None else None
        if set_down is not None:
            leg_time, drop = vertical_profile(
                set_down.height, options.vertical_leg_speed, options.max_acceleration, step
            )
            lowered = drones[-1] - drop[:, None, None] * np.array([0.0, 0.0, 1.0])
            time = np.concatenate([time, time[-1] + leg_time[1:]])
            drones = np.concatenate([drones, lowered[1:]])
        # a uniform step of at most ``step`` that ends on the plan's end
        samples = np.linspace(0.0, time[-1], max(2, int(np.ceil(time[-1] / step)) + 1))
        step = float(samples[1] - samples[0])
        flat = drones.reshape(len(time), 9)
        position = np.stack([np.interp(samples, time, flat[:, i]) for i in range(9)], axis=1)
        window = max(5, 2 * round(DERIVATIVE_WINDOW_S / step / 2) + 1)
        window = min(window, len(samples) - (1 - len(samples) % 2))
        velocity = acceleration = np.zeros_like(position)
        if window >= 5:
            # the fit at either end sees the hold beside it, where the drone rests: fitted
            # to the motion alone, it extrapolated the first segments' steady speed and
            # told a drone to brake before it had moved
            half = window // 2
            held = np.pad(position, ((half, half), (0, 0)), mode="edge")
            velocity = savgol_filter(held, window, 3, deriv=1, delta=step, axis=0)[half:-half]
            acceleration = savgol_filter(held, window, 3, deriv=2, delta=step, axis=0)[half:-half]
        # from rest, to rest: the hold before the release and the hold at the end
        velocity[[0, -1]] = 0.0
        acceleration[[0, -1]] = 0.0
        start = track.drones[0]
        homes = np.concatenate([start[:, :2], np.full((3, 1), options.home_height)], axis=1)
        shape = (len(samples), 3, 3)
        return cls(
            samples,
            position.reshape(shape) - homes,
            velocity.reshape(shape),
            acceleration.reshape(shape),
            homes,
            set_down_start,
        )
