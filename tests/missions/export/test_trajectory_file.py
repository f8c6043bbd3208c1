"""Trajectory files read by an independent CSV reader: NED columns of the ENU plan."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from flycrane.errors import InputError
from missions.export.trajectory_file import read_trajectory_text, trajectory_text
from missions.options import GeodeticOrigin
from missions.trajectory.drone_trajectory import DroneTrajectory


def test_columns_are_north_east_down_of_the_east_north_up_plan():
    time = np.array([0.0, 0.05, 0.1])
    enu = np.array([[1.0, 2.0, 3.0], [1.5, 2.5, 3.5], [2.0, 3.0, 4.0]])
    three = np.stack([enu * 7, enu, enu * 9], axis=1)  # drone 2 is the second
    homes = np.array([[5.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-5.0, 0.0, 1.0]])
    origin = GeodeticOrigin(latitude=47.5, longitude=8.5, altitude=488.1)
    trajectory = DroneTrajectory(time, three, three * 10, three * 100, homes)
    text = trajectory_text(trajectory, 2, origin, "bridge")
    lines = text.splitlines()
    assert lines[0] == "# FlyCrane trajectory v1: drone 2 of task 'bridge'"
    rows = list(csv.DictReader(io.StringIO("\n".join(lines[3:]))))
    assert [float(r["time"]) for r in rows] == [0.0, 0.05, 0.1]
    assert [float(r["north"]) for r in rows] == [2.0, 2.5, 3.0]
    assert [float(r["down"]) for r in rows] == [-3.0, -3.5, -4.0]
    assert float(rows[1]["v_east"]) == 15.0 and float(rows[2]["a_down"]) == -400.0
    t, data, home, set_down = read_trajectory_text(text)
    np.testing.assert_allclose(t, time)
    assert home == (47.5, 8.5, 488.1) and data.shape == (3, 9) and set_down is None


def test_a_file_of_another_kind_is_refused_with_its_name():
    with pytest.raises(InputError, match=r"drone1\.trajectory\.csv: not a FlyCrane"):
        read_trajectory_text("time,x\n0,1\n", "drone1.trajectory.csv")
