"""Each drone's trajectory as a file: ``drone{k}.trajectory.csv`` beside its mission.

Plain CSV with a commented header, readable by a ground station, a spreadsheet or an
onboard player::

    # FlyCrane trajectory v1: drone 2 of task "bridge"
    # frame: NED [m] from home; home: 47.39770315, 8.54559512, 488.100 (lat, lon [deg], AMSL [m])
    # time from the release [s]; velocity [m/s]; acceleration [m/s^2]
    time,north,east,down,v_north,v_east,v_down,a_north,a_east,a_down
    0.000,-0.404145,0.700000,-2.350000,0,0,0,0,0,0
    ...

Home is where the drone stands at arming, ``home_height`` above the ground below its start
(ArduPilot sets home there; the missions' relative altitudes count from it). Rows are
``SAMPLE_STEP_S`` apart; read between them with cubic Hermite interpolation of position
and velocity (:meth:`~missions.trajectory.drone_trajectory.DroneTrajectory.at`).
"""

from __future__ import annotations

import io
import re

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FieldProblem, InputError
from missions.geodesy import geodetic_from_enu, ned_from_enu
from missions.options import GeodeticOrigin
from missions.trajectory.drone_trajectory import DroneTrajectory

COLUMNS = "time,north,east,down,v_north,v_east,v_down,a_north,a_east,a_down"
VERSION = "FlyCrane trajectory v1"
_HOME = re.compile(r"home: ([-0-9.]+), ([-0-9.]+), ([-0-9.]+)")
_SET_DOWN = re.compile(r"set-down from ([-0-9.]+) s")


def trajectory_text(
    trajectory: DroneTrajectory, drone: int, origin: GeodeticOrigin, task_name: str = ""
) -> str:
    """The file of drone ``drone`` (1-based) of ``trajectory``, its home in WGS84 from the
    task's ``origin``."""
    k = drone - 1
    rows = np.column_stack(
        [
            trajectory.time,
            ned_from_enu(trajectory.position[:, k]),
            ned_from_enu(trajectory.velocity[:, k]),
            ned_from_enu(trajectory.acceleration[:, k]),
        ]
    )
    lat, lon, alt = (float(c[k]) for c in geodetic_from_enu(trajectory.homes, origin))
    out = io.StringIO()
    out.write(f"# {VERSION}: drone {drone} of task {task_name!r}\n")
    out.write(f"# frame: NED [m] from home; home: {lat:.8f}, {lon:.8f}, {alt:.3f} ")
    out.write("(lat, lon [deg], AMSL [m])\n")
    out.write("# time from the release [s]; velocity [m/s]; acceleration [m/s^2]")
    if trajectory.set_down_start is not None:
        out.write(f"; set-down from {trajectory.set_down_start:.3f} s")
    out.write("\n")
    out.write(COLUMNS + "\n")
    np.savetxt(out, rows, fmt=["%.3f"] + ["%.6f"] * 9, delimiter=",")
    return out.getvalue()


def read_trajectory_text(
    text: str, source: str = "trajectory"
) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[float, float, float], float | None]:
    """Inverse of :func:`trajectory_text`: time (N,), rows (N, 9) NED position, velocity,
    acceleration, home, and the set-down's start (None without one).

    Raises
    ------
    InputError
        Not a trajectory file of this version (field ``source``).
    """
    lines = text.splitlines()
    home = next((m for m in map(_HOME.search, lines[:3]) if m), None)
    if not lines or VERSION not in lines[0] or home is None or COLUMNS not in lines[:5]:
        raise InputError([FieldProblem(source, f"not a {VERSION} file")])
    try:
        data = np.loadtxt(io.StringIO(text), delimiter=",", comments="#", skiprows=4, ndmin=2)
    except ValueError as error:
        raise InputError([FieldProblem(source, str(error))]) from None
    if data.shape[1] != 10 or len(data) < 2 or not np.isfinite(data).all():
        raise InputError([FieldProblem(source, "rows must be 10 finite numbers, two or more")])
    set_down = next((m for m in map(_SET_DOWN.search, lines[:3]) if m), None)
    return (
        data[:, 0],
        data[:, 1:],
        (float(home[1]), float(home[2]), float(home[3])),
        float(set_down[1]) if set_down else None,
    )
