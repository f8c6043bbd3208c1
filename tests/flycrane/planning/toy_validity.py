"""A small validity checker for planner tests: real statics, bounds, and box obstacles
that forbid the platform point P and the drones (no fcl), so planner tests do not depend on
the collision layer."""

from __future__ import annotations

import numpy as np

from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.model.statics_kernel import configuration_cost
from flycrane.planning.state_space import ConfigurationSpace

RESOLUTION = 0.05


class ToyValidity:
    def __init__(self, system: CableSystem, space: ConfigurationSpace, boxes=()):
        self.system, self.space = system, space
        self.boxes = [(np.asarray(lo, float), np.asarray(hi, float)) for lo, hi in boxes]
        self.checks = 0

    def cost(self, q):
        q = np.atleast_2d(q)
        c = configuration_cost(self.system, q)
        c[~self.space.contains(q)] = np.inf
        return c

    def _free(self, q):
        points = np.concatenate(
            [q[:, None, :3], drone_positions_from_configuration(self.system, q)], axis=1
        )
        free = np.ones(len(q), dtype=bool)
        for lo, hi in self.boxes:
            free &= ~np.any(np.all((points >= lo) & (points <= hi), axis=2), axis=1)
        return free

    def is_valid(self, q):
        q = np.atleast_2d(q)
        self.checks += len(q)
        return np.isfinite(self.cost(q)) & self._free(q)

    def motion_is_valid(self, a, b):
        steps = max(1, int(np.ceil(self.space.distance(a, b)[0] / RESOLUTION)))
        return bool(self.is_valid(self.space.interpolate(a, b, np.linspace(0, 1, steps + 1))).all())

    def describe_invalid(self, q):
        return "infeasible or in a box"
