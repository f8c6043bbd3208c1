"""Samplers of the planner: uniform, and two narrow-passage samplers measured against it.

- ``uniform``: :meth:`ConfigurationSpace.sample_uniform` (position box, tilt uniform on
  the cap, torsion and alphas uniform).
- ``gaussian`` (Boor, Overmars, van der Stappen, ICRA 1999): a uniform q1 and q2 = q1 +
  Gaussian noise; keep whichever is valid when exactly one is. Samples gather along the
  boundary of the free space.
- ``bridge`` (Hsu et al., "The bridge test", ICRA 2003): q1 uniform, q2 = q1 + Gaussian
  noise, both invalid, their midpoint valid: samples gather in passages narrower than the
  noise.

Validity here is that of the platform *pose*: a pose is valid if its platform and payload
touch nothing and some formation makes it valid: the start's alphas repaired
(:func:`~flycrane.planning.extension_kernel.repair_alphas`) as the planner repairs its
nodes, or else one chosen drone by drone
(:func:`~flycrane.planning.extension_kernel.choose_formation`). With the sampled alphas
alone, most tilted candidates are statically infeasible (15 % feasible at tilt <= 0.3 over
alphas in [0.3, 1.8]) and the samples would gather on statics boundaries, not in the
obstacles' passages. A kept sample carries the formation that made it valid.

The narrow-passage samplers mix with uniform samples (NARROW_SHARE of the samples, when
they have any), so the planner stays probabilistically complete.
"""

from __future__ import annotations

from typing import Protocol

import numba
import numpy as np
from numpy.typing import NDArray

from flycrane.collision_kernel import pose_free
from flycrane.planning.extension_kernel import choose_formation, repair_alphas
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.planning.validity_kernel import in_bounds

#: Share of the samples taken from a narrow-passage sampler (when it has any).
NARROW_SHARE = 0.5
#: Candidates per refill of a narrow-passage sampler's buffer.
BATCH = 64
#: Gaussian noise of the second configuration: position [m], angles [rad].
SIGMA_POSITION = 0.8
SIGMA_ANGLE = 0.15


class Sampler(Protocol):
    def next(self) -> NDArray[np.float64]:
        """The next configuration to extend towards (9,)."""


class UniformSampler:
    def __init__(self, space: ConfigurationSpace, rng: np.random.Generator) -> None:
        self.space, self.rng = space, rng
        self.buffer = np.empty((0, 9))

    def next(self) -> NDArray[np.float64]:
        if not len(self.buffer):
            self.buffer = self.space.sample_uniform(self.rng, 256)
        q, self.buffer = self.buffer[0], self.buffer[1:]
        return q


@numba.njit(cache=True, nogil=True)
def _pose_valid(q, alphas, model, work, out) -> None:
    """Whether each pose (N, 9) admits a valid formation, written into q's alphas: the
    platform and payload must touch nothing (no alpha moves them), then ``alphas`` (3,)
    repaired, or else :func:`choose_formation` near them."""
    kin, scene = model[2], model[3]
    for row in range(q.shape[0]):
        out[row] = False
        if not (in_bounds(q[row], model[0]) and pose_free(q[row], kin, scene, work[4:10])):
            continue
        for k in range(3):
            q[row, 6 + k] = alphas[k]
        if repair_alphas(q[row], model, work, work[-1][2]) < np.inf:
            out[row] = True
        elif choose_formation(q[row], alphas, model, work, work[-1][2]):
            out[row] = repair_alphas(q[row], model, work, work[-1][2]) < np.inf


class NarrowPassageSampler:
    """Gaussian or bridge-test samples mixed with uniform ones (module docstring)."""

    def __init__(self, kind: str, space: ConfigurationSpace, validity, seed: int, alphas):
        self.kind, self.space, self.validity = kind, space, validity
        self.rng = np.random.default_rng([seed, 1])
        self.uniform = UniformSampler(space, np.random.default_rng(seed))
        self.alphas = np.asarray(alphas, dtype=float)
        self.buffer = np.empty((0, 9))
        self.generated = self.kept = 0

    def _valid(self, q: NDArray) -> NDArray[np.bool_]:
        """Pose validity (module docstring); q's alphas become the formation found."""
        out = np.empty(len(q), dtype=np.bool_)
        _pose_valid(q, self.alphas, self.validity.compiled.model, self.validity.work, out)
        return out

    def _near(self, q: NDArray) -> NDArray:
        other = np.ascontiguousarray(q.copy())
        other[:, :3] += self.rng.normal(0.0, SIGMA_POSITION, (len(q), 3))
        other[:, 3:6] += self.rng.normal(0.0, SIGMA_ANGLE, (len(q), 3))
        other[:, 4] = np.abs(other[:, 4])  # a negative tilt is the opposite tilt axis
        return other

    def _refill(self) -> None:
        first = np.ascontiguousarray(self.space.sample_uniform(self.rng, BATCH))
        second = self._near(first)
        self.generated += BATCH
        if self.kind == "gaussian":
            ok1, ok2 = self._valid(first), self._valid(second)
            kept = np.concatenate([first[ok1 & ~ok2], second[ok2 & ~ok1]])
        else:
            ok1, ok2 = self._valid(first), self._valid(second)
            both = ~ok1 & ~ok2
            middle = self.space.interpolate(first[both], second[both], np.full(both.sum(), 0.5))
            kept = middle[self._valid(middle)] if len(middle) else middle
        self.kept += len(kept)
        self.buffer = kept

    def next(self) -> NDArray[np.float64]:
        if self.rng.random() < NARROW_SHARE:
            if not len(self.buffer):
                self._refill()
            if len(self.buffer):
                q, self.buffer = self.buffer[0], self.buffer[1:]
                return q
        return self.uniform.next()


def make_sampler(name: str, space: ConfigurationSpace, validity, seed: int, start=None) -> Sampler:
    """The sampler called ``name`` for a planner run with ``seed``."""
    if name == "uniform":
        return UniformSampler(space, np.random.default_rng(seed))
    alphas = np.full(3, 1.0) if start is None else np.asarray(start)[6:9]
    return NarrowPassageSampler(name, space, validity, seed, alphas)
