"""Anytime refinement of a solved path: lower its average cost avgC (design.md eq. 8's c,
its mean along the path, :mod:`flycrane.planning.metrics`) in the time it is given,
keeping the path valid, its end points, its maxC and every least margin of Fig. 6.

Why: bitrrt stops at its first solution, and smoothing and the polish leave most of its
path near the hovers' formation (alphas about 1), where drones leaning further out cost
several times less until a margin binds. c depends on the platform's orientation and the
alphas, not on its position, so the refinement keeps the path's curve through the scene
and moves its waypoints' orientations and formations downhill:

1. Densify: waypoints at most ``spacing`` apart along the local paths (the same curve; a
   local path one of whose pieces the checker refuses stays whole).
2. Sweep: each interior waypoint steps down the gradient of log c over a small rotation
   and its alphas (central differences on the compiled statics). Waypoints of one parity
   step at once: their local paths do not overlap, so each step is judged alone and the
   kept ones pass together. A step is kept when it lowers the path's avgC, does not raise
   the cost integral (IC) of its two local paths, keeps them within the margin floors and
   at or below the input's maxC, and the waypoint and both motions are valid. Kept steps
   grow, refused ones shrink; a moved waypoint's neighbours get a step back.
3. Shortcuts between random waypoints, kept on the same test.
4. When the sweeps and shortcuts change nothing, halve the spacing and go on (coarse to
   fine: a coarse waypoint moves a long stretch at once, where a lone fine one only bends
   the formation and raises IC), the last level the first at or below ``finest``.

The IC guard: avgC is a mean along the path, so a longer path through cheap configurations
lowers it; without the guard the refinement buys avgC with length. The margin floors: the
input's least slack, headroom and thrust margin, over its samples at the metrics
resolution or at Fig. 6's 101 points, whichever is higher: Fig. 6's points can miss the
input's bottleneck, and the refinement takes whole stretches down to their floor, where
they would read lower than the input did. ``benchmarks/anytime_improvement.py`` measures
what it gains and costs.

The robust margin, given the drones' errors (:class:`~flycrane.planning.robust_clearance.
RobustClearance`): a lower cost comes from leaning the drones out, and in some poses that
turns the payload much more for the same drone errors, past an obstacle too
(BENCHMARKS.md, "Anytime improvement"). So a change is also kept only if its new local
paths keep the robust margin of those they replace (or zero, the lower): the path's
robust margin stays at least the input's (or zero), to :data:`MARGIN_TOLERANCE`, by
which the finer levels' local paths, sampled elsewhere, may read it lower.

Deterministic for a seed (the shortcuts' draws) when it ends by converging, the usual
case; its termination condition cuts it where it is. Returns the path of least avgC it
has seen: the input itself if it found none lower.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from flycrane.errors import FieldProblem, InputError
from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import matrix_from_tilt_torsion, tilt_torsion_from_matrix
from flycrane.model.statics_kernel import compiled_statics, statics_margins
from flycrane.planning.interfaces import Validity
from flycrane.planning.metrics import METRICS_RESOLUTION
from flycrane.planning.result import TerminationCondition
from flycrane.planning.robust_clearance import RobustClearance
from flycrane.planning.state_space import ConfigurationSpace

#: Columns of a stretch's statistics: its length and cost integral (sums), then its largest
#: cost and least margins [N] over its samples (its first configuration, the stretch
#: before's last, excluded).
LENGTH, INTEGRAL, HIGHEST, SLACK, HEADROOM, THRUST = range(6)
SUMS, MARGINS = [LENGTH, INTEGRAL], [SLACK, HEADROOM, THRUST]
#: Least gain in avgC, relative, that counts as a change: rounding-level moves end a level.
GAIN_TOLERANCE = 1e-9
#: How much lower [m] the refined path's robust margin may read than the input's: each
#: change keeps the margin of what it replaces, but a finer level samples its local paths
#: at other places.
MARGIN_TOLERANCE = 0.005


@dataclass(frozen=True)
class RefinementConfig:
    """Parameters of the refinement; distances in the state space's metric (about m)."""

    spacing: float = 0.5  #: waypoint spacing of the first level
    finest: float = 0.06  #: the last level is the first whose spacing is at most this
    step: float = 0.1  #: a waypoint's first step
    max_step: float = 0.5
    min_step: float = 1e-3  #: a waypoint whose step shrinks below this has converged
    wake: float = 0.02  #: least step of a moved waypoint's neighbours
    probe: float = 1e-3  #: finite-difference step of the gradient
    shortcuts: int = 20  #: shortcut attempts per sweep
    resolution: float = METRICS_RESOLUTION  #: sampling step of avgC, IC and the margins
    reading: int = 100  #: Fig. 6's parts of the path, whose points bound the margin floors

    def __post_init__(self) -> None:
        checks = [
            ("spacing", self.spacing > 0, "must be > 0"),
            ("finest", 0 < self.finest <= self.spacing, "must be in (0, spacing]"),
            ("step", self.min_step <= self.step <= self.max_step, "must be in [min, max]"),
            ("min_step", self.min_step > 0, "must be > 0"),
            ("wake", self.wake >= 0, "must be >= 0"),
            ("probe", self.probe > 0, "must be > 0"),
            ("shortcuts", self.shortcuts >= 0, "must be >= 0"),
            ("resolution", self.resolution > 0, "must be > 0"),
            ("reading", self.reading >= 1, "must be >= 1"),
        ]
        problems = [FieldProblem(name, why) for name, ok, why in checks if not ok]
        if problems:
            raise InputError(problems, "refinement options")


def _points(
    a: NDArray, b: NDArray, space: ConfigurationSpace, step: float, ends: bool
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The local paths a -> b (K, 9) cut into ``parts`` pieces at most ``step`` long, as
    :meth:`ConfigurationSpace.discretize` cuts them: (configurations at index / parts,
    index 0 to parts - 1, or to parts with ``ends``; the local path of each; its index;
    parts (K,))."""
    parts = np.maximum(1, np.ceil(space.path_length(a, b) / step)).astype(int)
    count = parts + ends
    owner = np.repeat(np.arange(len(a)), count)
    index = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    return space.interpolate(a[owner], b[owner], index / parts[owner]), owner, index, parts


def _margins(system: CableSystem, q: NDArray) -> tuple[NDArray, NDArray]:
    """(cost (N,), least slack, headroom and thrust margin (N, 3) [N], -inf where
    infeasible) of configurations."""
    cost, margins = statics_margins(system, q)
    return cost, np.where(np.isfinite(cost)[:, None], margins, -np.inf)


def _statistics(
    a: NDArray, b: NDArray, space: ConfigurationSpace, system: CableSystem, resolution: float
) -> NDArray[np.float64]:
    """Statistics (K, 6) of the local paths a -> b (K, 9) sampled as the path metrics sample
    them, columns LENGTH ... THRUST; the integral trapezoidal in the local path's length."""
    q, owner, index, parts = _points(a, b, space, resolution, ends=True)
    cost, margins = _margins(system, q)
    cost[~space.contains(q)] = np.inf
    inner = index > 0
    starts = np.flatnonzero(~inner)
    trapezoid = np.where(inner & (index < parts[owner]), 1.0, 0.5)
    out = np.empty((len(a), 6))
    out[:, LENGTH] = space.path_length(a, b)
    out[:, INTEGRAL] = np.add.reduceat(trapezoid * cost, starts) * out[:, LENGTH] / parts
    out[:, HIGHEST] = np.maximum.reduceat(np.where(inner, cost, 0.0), starts)
    out[:, MARGINS] = np.minimum.reduceat(np.where(inner[:, None], margins, np.inf), starts)
    return out


def _joined(rows: NDArray, starts: NDArray) -> NDArray[np.float64]:
    """Statistics of consecutive stretches joined: rows[starts[n] : starts[n + 1]] each."""
    out = np.empty((len(starts), 6))
    out[:, SUMS] = np.add.reduceat(rows[:, SUMS], starts)
    out[:, HIGHEST] = np.maximum.reduceat(rows[:, HIGHEST], starts)
    out[:, MARGINS] = np.minimum.reduceat(rows[:, MARGINS], starts)
    return out


def _fractions(path: NDArray, space: ConfigurationSpace, parts: int) -> NDArray[np.float64]:
    """Configurations at ``parts`` + 1 equally spaced fractions of the path's length: Fig. 6's
    points (as :func:`flycrane.analysis.profiles.configurations_at_fractions`, which the
    planning layer does not import)."""
    cumulative = np.concatenate([[0.0], np.cumsum(space.distance(path[:-1], path[1:]))])
    s = np.linspace(0.0, 1.0, parts + 1) * cumulative[-1]
    segment = np.clip(np.searchsorted(cumulative, s, side="right") - 1, 0, len(path) - 2)
    span = cumulative[segment + 1] - cumulative[segment]
    t = np.divide(s - cumulative[segment], span, out=np.zeros_like(s), where=span > 0)
    return space.interpolate(path[segment], path[segment + 1], t)


def _moved(q: NDArray, u: NDArray, space: ConfigurationSpace) -> NDArray[np.float64]:
    """Configurations (N, 9) turned by u[:, :3] / rho_R (a rotation vector, world axes) and
    their alphas moved by u[:, 3:] / rho_a, kept in range: u (N, 6) is in the metric."""
    out = q.copy()
    turn = Rotation.from_rotvec(u[:, :3] / space.rotation_weight).as_matrix()
    out[:, 3:6] = tilt_torsion_from_matrix(turn @ matrix_from_tilt_torsion(q[:, 3:6]))
    alphas = q[:, 6:] + u[:, 3:] / space.alpha_weight
    out[:, 6:] = np.clip(alphas, space.alpha_low, space.alpha_high)
    return out


class _Refinement:
    """A path being refined: its waypoints, the statistics of its local paths, each
    waypoint's step, and the bounds every change keeps (those of the input path)."""

    def __init__(
        self,
        path: NDArray,
        space: ConfigurationSpace,
        validity: Validity,
        system: CableSystem,
        config: RefinementConfig,
        seed: int,
        robust: RobustClearance | None = None,
    ) -> None:
        self.space, self.validity, self.system, self.config = space, validity, system, config
        self.robust = robust
        self.rng = np.random.default_rng(seed)
        cost, margins = _margins(system, path[:1])
        #: The first waypoint as a stretch of its own, of no length: its cost and margins
        #: count in maxC and the margin floors.
        self.first = np.concatenate([[0.0, 0.0], cost, margins[0]])
        self.spacing = config.spacing
        self._use(path)
        whole = _joined(np.vstack([self.first, self.stats]), np.array([0]))[0]
        fig6 = _margins(system, _fractions(path, space, config.reading))[1].min(axis=0)
        self.floor = np.maximum(whole[MARGINS], fig6)
        self.ceiling = whole[HIGHEST]
        #: The path of least avgC so far: densifying samples the path anew, which can
        #: raise its avgC a little, so a level can end above the one before.
        self.best, self.best_average = path, self.average()
        self._use(self._split(path))

    def _use(self, path: NDArray) -> None:
        self.path = path
        c = self.config
        self.stats = _statistics(path[:-1], path[1:], self.space, self.system, c.resolution)
        self.steps = np.full(len(path), c.step)
        #: Each local path's robust margin, NaN until asked (:meth:`keeps_margin`).
        self.exposure = np.full(len(path) - 1, np.nan)

    def _split(self, path: NDArray) -> NDArray[np.float64]:
        """The path densified at the level's spacing, but for local paths one of whose
        pieces is invalid: the checker samples a piece elsewhere than the whole, and between
        the whole's samples a piece can graze an obstacle."""
        points, owner, index, _ = _points(path[:-1], path[1:], self.space, self.spacing, False)
        ends = np.concatenate([points[1:], path[-1:]])
        valid = self.validity.motion_is_valid
        broken = [not valid(a, b) for a, b in zip(points, ends, strict=True)]
        whole = np.bincount(owner, broken, minlength=len(path) - 1) == 0
        return np.concatenate([points[whole[owner] | (index == 0)], path[-1:]])

    def finer(self) -> bool:
        """Halve the spacing and densify; False once the finest level is done."""
        self.keep_best()
        if self.spacing <= self.config.finest:
            return False
        self.spacing /= 2
        self._use(self._split(self.path))
        return True

    def keep_best(self) -> None:
        """Remember the path if its avgC is the least so far."""
        if self.average() < self.best_average:
            self.best, self.best_average = self.path.copy(), self.average()

    def average(self) -> float:
        """avgC of the path, as :func:`~flycrane.planning.metrics.path_metrics` has it."""
        length = self.stats[:, LENGTH].sum()
        if not length > 0.0:
            return float(self.first[HIGHEST])
        return float(self.stats[:, INTEGRAL].sum() / length)

    def kept(self, old: NDArray, new: NDArray) -> NDArray[np.bool_]:
        """Which replacements of stretches, old sums (K, 2) by new statistics (K, 6), lower
        avgC without raising IC or maxC and keep the margin floors. Each is judged alone;
        avgC's test is linear in the sums, so replacements that do not overlap pass
        together."""
        average = self.average()
        gain = (old[:, 1] - average * old[:, 0]) - (new[:, INTEGRAL] - average * new[:, LENGTH])
        return (
            np.isfinite(new[:, INTEGRAL])
            & (gain > GAIN_TOLERANCE * average)
            & (new[:, INTEGRAL] <= old[:, 1])
            & (new[:, HIGHEST] <= self.ceiling)
            & (new[:, MARGINS] >= self.floor).all(axis=1)
        )

    def sweep(self, parity: int) -> bool:
        """A step of every interior waypoint of one parity that has not converged; whether
        one moved."""
        c, space = self.config, self.space
        j = np.arange(1 + parity, len(self.path) - 1, 2)
        j = j[self.steps[j] >= c.min_step]
        if not len(j):
            return False
        a, b = self.path[j - 1], self.path[j + 1]
        q = _moved(self.path[j], self.steps[j, None] * self.descent(self.path[j]), space)
        new = _statistics(
            np.concatenate([a, q]), np.concatenate([q, b]), space, self.system, c.resolution
        )
        pairs = np.stack([new[: len(j)], new[len(j) :]], axis=1).reshape(-1, 6)
        old = self.stats[j - 1][:, SUMS] + self.stats[j][:, SUMS]
        moves = np.flatnonzero(self.kept(old, _joined(pairs, np.arange(0, len(pairs), 2))))
        moves = moves[self.validity.is_valid(q[moves])]
        valid = self.validity.motion_is_valid
        moves = np.array([n for n in moves if valid(a[n], q[n]) and valid(q[n], b[n])], int)
        margins = {
            n: self.keeps_margin([j[n] - 1, j[n]], [(a[n], q[n]), (q[n], b[n])]) for n in moves
        }
        moves = np.array([n for n in moves if margins[n] is not None], int)
        moved = np.zeros(len(j), dtype=bool)
        moved[moves] = True
        self.steps[j[~moved]] *= 0.5
        w = j[moved]
        self.path[w] = q[moved]
        self.stats[w - 1], self.stats[w] = new[: len(j)][moved], new[len(j) :][moved]
        for n in moves:
            self.exposure[[j[n] - 1, j[n]]] = margins[n]
        self.steps[w] = np.minimum(self.steps[w] * 1.5, c.max_step)
        for neighbour in (w - 1, w + 1):
            self.steps[neighbour] = np.maximum(self.steps[neighbour], c.wake)
        return bool(len(w))

    def keeps_margin(self, old: list[int], new: list[tuple[NDArray, NDArray]]) -> NDArray | None:
        """The robust margins of the local paths ``new`` that would replace the path's local
        paths ``old`` (indices), if the least of them is at least the old ones' least (or
        zero, the lower); None if not. Without a robust clearance, NaNs."""
        if self.robust is None:
            return np.full(len(new), np.nan)
        floor = min(min(self._exposure(i) for i in old), 0.0)
        margins = np.full(len(new), np.nan)
        for m, (a, b) in enumerate(new):
            margins[m] = self._margin(a, b)
            if margins[m] < floor:
                return None
        return margins

    def _exposure(self, i: int) -> float:
        if np.isnan(self.exposure[i]):
            self.exposure[i] = self._margin(self.path[i], self.path[i + 1])
        return float(self.exposure[i])

    def _margin(self, a: NDArray, b: NDArray) -> float:
        assert self.robust is not None
        samples = self.space.discretize(a, b, self.robust.resolution)
        return self.robust.samples_margin(samples)

    def descent(self, q: NDArray) -> NDArray[np.float64]:
        """Unit directions (N, 6) in the metric down log c at configurations (N, 9), over a
        rotation and the alphas (zero where c is flat, or infinite around q)."""
        probes = np.vstack([np.eye(6), -np.eye(6)]) * self.config.probe
        around = _moved(np.repeat(q, 12, axis=0), np.tile(probes, (len(q), 1)), self.space)
        with np.errstate(invalid="ignore"):
            log_cost = np.log(compiled_statics(self.system, around)[3]).reshape(len(q), 2, 6)
            slope = (log_cost[:, 0] - log_cost[:, 1]) / (2 * self.config.probe)
        slope[~np.isfinite(slope)] = 0.0
        norm = np.linalg.norm(slope, axis=1, keepdims=True)
        return -np.divide(slope, norm, out=np.zeros_like(slope), where=norm > 0)

    def shortcut(self) -> bool:
        """``config.shortcuts`` random shortcuts between waypoints (straight local paths at
        the level's spacing); those kept that overlap none kept before. Whether one was."""
        c, space = self.config, self.space
        if len(self.path) < 3 or not c.shortcuts:
            return False
        i = self.rng.integers(0, len(self.path) - 2, c.shortcuts)
        k = i + 2 + (self.rng.random(c.shortcuts) * (len(self.path) - i - 2)).astype(int)
        a, _, index, counts = _points(self.path[i], self.path[k], space, self.spacing, False)
        # Each shortcut's pieces: from its points to the next, its last one to its end.
        b = np.roll(a, -1, axis=0)
        last = np.flatnonzero(np.concatenate([index[1:] == 0, [True]]))
        b[last] = self.path[k]
        starts = np.flatnonzero(index == 0)
        rows = _statistics(a, b, space, self.system, c.resolution)
        sums = np.vstack([np.zeros(2), np.cumsum(self.stats[:, SUMS], axis=0)])
        kept = np.flatnonzero(self.kept(sums[k] - sums[i], _joined(rows, starts)))
        taken = np.zeros(len(self.path), dtype=bool)
        # From the path's end backwards: a splice leaves the indices before it as they were.
        for n in sorted(kept, key=lambda n: -i[n]):
            x, y, s = i[n], k[n], slice(starts[n], starts[n] + counts[n])
            pieces = list(zip(a[s], b[s], strict=True))
            if taken[x : y + 1].any() or not all(
                self.validity.motion_is_valid(p, q) for p, q in pieces
            ):
                continue
            margins = self.keeps_margin(list(range(x, y)), pieces)
            if margins is None:
                continue
            taken[x : y + 1] = True
            self.path = np.concatenate([self.path[: x + 1], b[s][:-1], self.path[y:]])
            self.stats = np.concatenate([self.stats[:x], rows[s], self.stats[y:]])
            self.exposure = np.concatenate([self.exposure[:x], margins, self.exposure[y:]])
            fresh = np.full(counts[n] - 1, c.step)
            self.steps = np.concatenate([self.steps[: x + 1], fresh, self.steps[y:]])
        return bool(taken.any())


def refine_path(
    path: NDArray[np.float64],
    space: ConfigurationSpace,
    validity: Validity,
    system: CableSystem,
    config: RefinementConfig,
    termination: TerminationCondition,
    seed: int = 0,
    robust: RobustClearance | None = None,
) -> NDArray[np.float64]:
    """The path of least avgC found, valid, with the same end points, least margins at
    least as good and, with ``robust``, a robust margin as good (module docstring); the
    input itself if none was. (M', 9)."""
    path = np.array(path, dtype=float)
    if len(path) < 2 or termination() is not None:
        return path
    refinement = _Refinement(path, space, validity, system, config, seed, robust)
    phases: tuple[Callable[[], bool], ...] = (
        partial(refinement.sweep, 1),
        partial(refinement.sweep, 0),
        refinement.shortcut,
    )
    unchanged = 0  # phases in a row that changed nothing: all of them, the level is done
    for phase in itertools.cycle(phases):
        if termination() is not None:
            break
        unchanged = 0 if phase() else unchanged + 1
        if unchanged == len(phases):
            if not refinement.finer():
                break
            unchanged = 0
    refinement.keep_best()
    return refinement.best
