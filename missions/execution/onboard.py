"""The onboard executor: each drone plays its own trajectory, the ground keeps the clock.

Stock ArduCopter (>= 4.5, Lua scripting, no firmware fork): the player
``lua/flycrane_player.lua`` runs on every drone (copied into its scripts directory, read at
boot) and plays the trajectory file the ground put on the drone by MAVLink FTP
(:func:`upload`) during the mission's NAV_SCRIPT_TIME item (:mod:`missions.export.onboard`).
The ground releases the three into that item together (MISSION_SET_CURRENT back to back)
and sends each drone the group clock's segments in its own boot time
(:func:`missions.mavlink.guided.group_time`): whenever the clock changes, and every
``resend_s`` so that a lost message is made good.

Through a lost link a drone keeps playing the last segment it got, on its own clock, so the
three stay in step as long as the ground does not change the clock; the ground therefore
stops changing it once it has lost a drone (a stop that drone could not hear would split
the team) and only reports. Other faults stop the team as in the stream executor.
"""

from __future__ import annotations

import time
from pathlib import Path

from missions.autopilots.ardupilot import COPTER_MODES
from missions.execution.executor import Executor
from missions.execution.group_clock import Segment
from missions.export.onboard import player_file
from missions.mavlink.commands import release
from missions.mavlink.ftp import put_file
from missions.mavlink.guided import group_time

#: The player script, to be copied into each drone's scripts directory.
PLAYER_SCRIPT = Path(__file__).with_name("lua") / "flycrane_player.lua"
#: Where the player reads its trajectory (the root of the drone's file system).
TRAJECTORY_REMOTE = "/flycrane_trajectory.bin"


class OnboardExecutor(Executor):
    """The drones' players keep the plan; the ground sends the clock (module docstring)."""

    mode = "onboard"
    expected_mode = COPTER_MODES["AUTO"]
    link_loss_stops = False
    resend_s = 0.5  #: [s of common time] between repeats of the current segment

    def __init__(self, *args, player_seq: int, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.player_seq = player_seq  #: the NAV_SCRIPT_TIME item of every mission
        self._sent: list[tuple[int, float]] = [(0, -1.0)] * 3  #: (segments, common time)
        #: per drone, every (common time, segments) sent to it
        self._history: list[list[tuple[float, int]]] = [[], [], []]

    def upload(self, timeout: float) -> None:
        """Put each drone's trajectory on it (MAVLink FTP).

        Raises
        ------
        FtpError
            A vehicle refused the file or did not take it within ``timeout`` [s].
        """
        trajectory = self.trajectory
        for k, link in enumerate(self.links):
            data = player_file(
                trajectory.time,
                trajectory.position[:, k],
                trajectory.velocity[:, k],
                trajectory.acceleration[:, k],
                trajectory.homes[k],
                self.origin,
            )
            put_file(link, data, TRAJECTORY_REMOTE, timeout)

    def engage(self, timeout: float) -> None:
        """Release the three into the player's item together; the players hold their first
        point until the clock reaches them."""
        release(self.links, self.player_seq, self.retry)
        deadline = time.monotonic() + timeout
        while any(v.mode != self.expected_mode for v in self.vehicles):
            if time.monotonic() > deadline:
                raise TimeoutError(f"not all in AUTO within {timeout:.0f} s")
            time.sleep(0.01)

    def _command(self, t: float) -> None:
        """The clock's last segment to every reachable drone, when it is new to it or
        ``resend_s`` after it was last sent."""
        assert self.clock is not None
        segments = self.clock.segments
        last: Segment = segments[-1]
        for k, (link, vehicle) in enumerate(zip(self.links, self.vehicles, strict=True)):
            count, when = self._sent[k]
            if k in self.cut or (count == len(segments) and t - when < self.resend_s):
                continue
            start_ms = round((last.start - float(vehicle.offset or 0.0)) * 1000)
            link.send(group_time(start_ms, last.tau, last.rate, last.rate_end, last.ramp,
                                 len(segments), self.lead))  # fmt: skip
            self._sent[k] = (len(segments), t)
            self._history[k].append((t, len(segments)))

    def _lost(self, k: int) -> None:
        """Drone k plays the last segment it got before it went silent: if the clock
        changed since, the other two rejoin that segment's law, so that the three stay on
        one clock."""
        assert self.clock is not None
        heard = self.monitor.drones[k].last_heard
        got = [count for at, count in self._history[k] if heard is None or at <= heard]
        if got and got[-1] < len(self.clock.segments):
            start = max(self.present(), self.clock.segments[-1].start)
            self.clock.rejoin(start, self.clock.segments[got[-1] - 1])
