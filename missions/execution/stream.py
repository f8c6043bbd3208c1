"""The stream executor: the ground flies all three drones on targets from one clock.

Each drone flies in GUIDED on position + velocity + acceleration targets
(SET_POSITION_TARGET_LOCAL_NED, :mod:`missions.mavlink.guided`), one a tick, in its local
NED frame (:mod:`.vehicles`). The target of drone k is its trajectory at plan time
tau(t_k + lead), t_k its own present on the common clock and the lead what its controller
lags a target by (:attr:`~.executor.Executor.default_lead`), with the velocity scaled by
the clock's rate and the acceleration by its square plus the velocity times the rate's
change: slowing or stopping the clock slows or stops all three on the plan. ArduCopter
moves a target on with its last velocity between two targets, so one that comes late costs
little; without a new one for GUID_TIMEOUT it holds (the .parm sets it short,
:mod:`missions.autopilots.ardupilot`).

PX4's OFFBOARD mode takes the same message (it needs targets above 2 Hz for a second
before it engages); only ArduCopter is tested here.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.ardupilot import COPTER_MODES
from missions.execution.executor import Executor
from missions.mavlink.guided import position_target, set_mode_message


class StreamExecutor(Executor):
    """The ground streams targets (module docstring)."""

    mode = "stream"
    expected_mode = COPTER_MODES["GUIDED"]
    anchors = True

    def engage(self, timeout: float) -> None:
        """Targets at plan time 0 (each drone's start, where it holds), then GUIDED on the
        three back to back; returns once every one reports GUIDED.

        Raises
        ------
        TimeoutError
            A vehicle is not in GUIDED by ``timeout`` [s of ground time].
        """
        self._send_targets()
        for link in self.links:
            link.send(set_mode_message(self.expected_mode, link.target))
        deadline = time.monotonic() + timeout
        while any(v.mode != self.expected_mode for v in self.vehicles):
            if time.monotonic() > deadline:
                modes = [v.mode for v in self.vehicles]
                raise TimeoutError(f"not all in GUIDED within {timeout:.0f} s: modes {modes}")
            self._send_targets()
            time.sleep(0.02 / self.speedup)

    def _send_targets(self) -> None:
        """Every reachable drone's target, its :attr:`lead` ahead of its own present."""
        for k, (link, vehicle) in enumerate(zip(self.links, self.vehicles, strict=True)):
            boot = vehicle.boot_time()
            if k in self.cut or boot is None or not self.frames:
                continue
            now = boot + float(vehicle.offset or 0.0)
            p, v, a = self._led(k, now)
            frame = self.frames[k]
            local = frame.local_position(p + self.trajectory.homes[k])
            link.send(position_target(round(boot * 1000), link.target, local,
                                      frame.local_vector(v), frame.local_vector(a)))  # fmt: skip

    def _led(self, k: int, now: float) -> tuple[NDArray, NDArray, NDArray]:
        """Drone k's target :attr:`lead` ahead of its present ``now``: east and north
        from the horizontal lead, up from the vertical."""
        horizontal, vertical = self.lead
        across = self.commanded(k, now + horizontal)
        up = self.commanded(k, now + vertical)
        p, v, a = (np.concatenate([x[:2], z[2:]]) for x, z in zip(across, up, strict=True))
        return p, v, a

    def _command(self, t: float) -> None:
        self._send_targets()
