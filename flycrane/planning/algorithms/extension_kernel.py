"""Compiled pieces of a tree extension: embedding, alpha repair, extend, partial advance.

One extension (:func:`extend`) is one compiled call: step from the near node towards a
target along the local path, repair the formation (the alphas) at the new pose, check the
new configuration and the motion to it (:mod:`flycrane.planning.validity_kernel`).

Alpha repair. For a platform pose the three alphas are redundant: they change the drones'
positions, hence the cost and the drones' and cables' collisions, not the load's. Starting
from the near node's alphas (the extension's warm start), a few steps of descent on the
repair's objective over the alphas, with finite differences and backtracking, move them
towards its least value that is collision-free (an invalid configuration counts as +inf,
so the descent stops at obstacles and infeasibility). It is bounded (ALPHA_STEP per step,
REPAIR_STEPS steps) so each extension moves the alphas by little, and the motion check
covers the change.

The repair's objective is ``log c + w log c_cap`` (:func:`repair_objective`): eq. 8, plus
eq. 8 again with each of its factors capped at the least factor of its kind (slack,
overload, thrust) that the path's two endpoints have; ``w`` is
:attr:`~flycrane.planning.algorithms.bitrrt.BiTRRTConfig.margin_weight`. So a margin counts (1 + w)
times below what the endpoints keep and once above it. Why: eq. 8 multiplies twelve
tension factors against three thrust factors, and its least value at a strained pose (the
Puzzle's tilted passage) lies at low alphas, where it buys slack the path cannot keep
anyway (every path hovers at its endpoints, which bound its least margins) with thrust and
headroom it can: on eq. 8 alone bitrrt's paths kept less thrust margin than T-RRT's
(BENCHMARKS.md, "Planner v2, the default").
"""

from __future__ import annotations

import math

import numpy as np

from flycrane.kernels import kernel
from flycrane.model.statics_kernel import statics_row
from flycrane.planning.algorithms.neighbours import EMBEDDING
from flycrane.planning.interpolation import geodesic_length, interpolate_into
from flycrane.planning.validity_kernel import (
    collisions_free,
    in_bounds,
    motion_check,
    motion_last_valid,
    state_check,
)
from flycrane.world.collision_kernel import drone_free, pose_free

#: Repair: finite-difference step and largest step of each descent step [rad].
ALPHA_PROBE = 0.01
ALPHA_STEP = 0.15
#: Repair: descent steps per extension.
REPAIR_STEPS = 2
#: extend's outcomes: BLOCKED means a valid new configuration the straight motion cannot
#: reach (see :func:`reshape_first`).
FAILED, ADVANCED, REACHED, BLOCKED = 0, 1, 2, 3


@kernel()
def embed_into(q, weights, out) -> None:
    """E(q) of :meth:`ConfigurationSpace.embed` into out (18,)."""
    phi, theta, sigma = q[3], q[4], q[5]
    cp, sp, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    cs, ss = math.cos(sigma - phi), math.sin(sigma - phi)
    scale = weights[0] / math.sqrt(2.0)
    out[0], out[1], out[2] = q[0], q[1], q[2]
    out[3] = scale * (cp * ct * cs - sp * ss)
    out[4] = scale * (-cp * ct * ss - sp * cs)
    out[5] = scale * cp * st
    out[6] = scale * (sp * ct * cs + cp * ss)
    out[7] = scale * (-sp * ct * ss + cp * cs)
    out[8] = scale * sp * st
    out[9] = scale * -st * cs
    out[10] = scale * st * ss
    out[11] = scale * ct
    for k in range(3):
        out[12 + k] = weights[1] * math.cos(q[6 + k])
        out[15 + k] = weights[1] * math.sin(q[6 + k])


@kernel()
def repair_objective(smodel, f0, v, m, caps) -> float:
    """The repair's objective (module docstring) of a feasible configuration from its
    statics, :func:`statics_row`'s f0 (6,), v (6,), m (3,): log c + caps[3] x log c_cap,
    c_cap being eq. 8 with its slack, overload and thrust factors capped at caps[0],
    caps[1] and caps[2]. The planner's checker evaluates eq. 8's normalized form, whose
    factors these are."""
    thrust_max, f_lo, f_hi = smodel[7], smodel[8], smodel[9]
    log_cost, log_capped = 0.0, 0.0
    for i in range(6):
        span = f_hi[i] - f_lo[i]
        slack = (f0[i] - v[i] - f_lo[i]) / span
        overload = (f_hi[i] - f0[i] - v[i]) / span
        log_cost -= math.log(slack) + math.log(overload)
        log_capped -= math.log(min(slack, caps[0])) + math.log(min(overload, caps[1]))
    for k in range(3):
        thrust = (thrust_max[k] - m[k]) / thrust_max[k]
        log_cost -= math.log(thrust)
        log_capped -= math.log(min(thrust, caps[2]))
    return log_cost + caps[3] * log_capped


@kernel()
def _statics_objective(q, model, work, caps) -> tuple[float, float]:
    """(the repair's objective, the cost) of q without the collision check, (+inf, +inf)
    out of bounds or infeasible: the probes of a descent only need the slope."""
    bounds, smodel = model[0], model[1]
    if not in_bounds(q, bounds):
        return math.inf, math.inf
    cost = statics_row(q, smodel, work[1], work[2], work[3], work[0])
    if not cost < math.inf:
        return math.inf, math.inf
    return repair_objective(smodel, work[1], work[2], work[3], caps), cost


@kernel()
def _objective_below(q, model, work, caps, bound) -> tuple[float, float]:
    """(the repair's objective, the cost) of q if q is valid and its objective below
    ``bound``, else (+inf, +inf). The statics decide first: a configuration that does not
    improve on ``bound`` needs no collision check. Its cost comes along, so the
    configuration a repair ends at is never checked again."""
    value, cost = _statics_objective(q, model, work, caps)
    if not (value < bound and collisions_free(q, model, work)):
        return math.inf, math.inf
    return value, cost


@kernel()
def repair_alphas(q, model, work, gradient, caps, value, cost) -> float:
    """Descend the repair's objective over q's alphas in place (module docstring), from
    ``value`` and ``cost``, the objective and the cost at q (valid); returns the cost at
    the end. ``caps``:
    :func:`repair_objective`'s. The slope is probed on the statics alone (a collision check
    costs about as much as the statics again); every step taken is checked whole, so a
    step into an obstacle is refused and shortened."""
    bounds = model[0]
    low, high = bounds[7], bounds[8]
    for _ in range(REPAIR_STEPS):
        norm = 0.0
        for k in range(3):
            saved = q[6 + k]
            probe = ALPHA_PROBE if saved + ALPHA_PROBE <= high else -ALPHA_PROBE
            q[6 + k] = saved + probe
            shifted = _statics_objective(q, model, work, caps)[0]
            q[6 + k] = saved
            # A probe into infeasibility: push away from it.
            slope = (shifted - value) / probe if shifted < math.inf else 1e3 * np.sign(probe)
            gradient[k] = slope
            norm += slope * slope
        norm = math.sqrt(norm)
        if norm == 0.0:
            break
        step = ALPHA_STEP
        improved = False
        for _ in range(4):  # backtracking
            for k in range(3):
                gradient[3 + k] = q[6 + k]
                q[6 + k] = min(high, max(low, q[6 + k] - step * gradient[k] / norm))
            trial, trial_cost = _objective_below(q, model, work, caps, value)
            if trial < value:
                value, cost, improved = trial, trial_cost, True
                break
            for k in range(3):
                q[6 + k] = gradient[3 + k]
            step *= 0.5
        if not improved:
            break
    return cost


@kernel()
def _choose_alphas(near, target, out, model, work, scratch, caps) -> tuple[float, float]:
    """Start the repair from the valid one of least objective of: the near node's alphas
    (the warm start), the interpolated ones (out's), the target's; if none is valid,
    :func:`choose_formation` near the near node's. Returns the objective and the cost of
    out, +inf if nothing is valid. The
    candidates are ranked by their statics and checked for collisions in that order, so
    usually one collision check decides. ``scratch`` (18,): the candidates' alphas and
    objectives."""
    # candidates c at scratch[6 + 3c:], their objectives at scratch[15 + c], costs at scratch[c]
    for k in range(3):
        scratch[6 + k], scratch[9 + k], scratch[12 + k] = near[6 + k], out[6 + k], target[6 + k]
    for c in range(3):
        for k in range(3):
            out[6 + k] = scratch[6 + 3 * c + k]
        scratch[15 + c], scratch[c] = _statics_objective(out, model, work, caps)
    for _ in range(3):
        c = 0  # the least objective not yet tried, the first of equals
        for other in (1, 2):
            if scratch[15 + other] < scratch[15 + c]:
                c = other
        if not scratch[15 + c] < math.inf:
            break
        value, scratch[15 + c] = scratch[15 + c], math.inf  # tried
        for k in range(3):
            out[6 + k] = scratch[6 + 3 * c + k]
        if collisions_free(out, model, work):  # in bounds and feasible: ranked so
            return value, scratch[c]
    return choose_formation(out, near[6:9], model, work, scratch, caps)


#: Formation choice: alphas per drone scanned, and nearest free ones combined per drone.
FORMATION_GRID = 16
FORMATION_NEAREST = 3


@kernel()
def choose_formation(q, preferred, model, work, scratch, caps) -> tuple[float, float]:
    """Alphas for q's pose when none of the usual candidates is valid (module docstring):
    per drone, the FORMATION_NEAREST alphas of a FORMATION_GRID scan nearest to
    ``preferred`` (3,) at which that drone and its cables touch nothing; of their
    combinations, the valid one of least objective goes into q; returns its objective and
    its cost, +inf if none is valid.
    ``scratch`` (18,): drone k's nearest free alphas, nearest first, from
    FORMATION_NEAREST * k, their count at 12 + k, the best combination at 15."""
    bounds, _, kin, scene, _ = model
    collision_work = work[4:11]
    low, high = bounds[7], bounds[8]
    if not pose_free(q, kin, scene, collision_work):
        return math.inf, math.inf
    for k in range(3):
        row, count = FORMATION_NEAREST * k, 0
        for g in range(FORMATION_GRID):
            alpha = low + (high - low) * g / (FORMATION_GRID - 1)
            q[6 + k] = alpha
            if not drone_free(q, k, kin, scene, collision_work):
                continue
            distance = abs(alpha - preferred[k])
            m = count  # insert, after the free alphas as near, if among the nearest
            while m > 0 and abs(scratch[row + m - 1] - preferred[k]) > distance:
                if m < FORMATION_NEAREST:
                    scratch[row + m] = scratch[row + m - 1]
                m -= 1
            if m < FORMATION_NEAREST:
                scratch[row + m] = alpha
            count = min(count + 1, FORMATION_NEAREST)
        if count == 0:
            return math.inf, math.inf
        scratch[12 + k] = count
    best, best_cost, second, third = math.inf, math.inf, FORMATION_NEAREST, 2 * FORMATION_NEAREST
    for i in range(int(scratch[12])):
        for j in range(int(scratch[13])):
            for m in range(int(scratch[14])):
                q[6], q[7], q[8] = scratch[i], scratch[second + j], scratch[third + m]
                value, cost = _objective_below(q, model, work, caps, best)
                if value < best:
                    best, best_cost = value, cost
                    scratch[15], scratch[16], scratch[17] = q[6], q[7], q[8]
    q[6], q[7], q[8] = scratch[15], scratch[16], scratch[17]
    return best, best_cost


#: extend's repair modes: never; always (towards samples, whose alphas mean nothing);
#: short of the target only (towards another tree's node, which must be reached exactly).
NO_REPAIR, REPAIR, REPAIR_UNLESS_REACHED = 0, 1, 2


@kernel()
def extend(
    near, target, step, repair, partial, resolution, model, work, out, caps
) -> tuple[int, float]:
    """One extension from ``near`` towards ``target`` into ``out`` (9,): (outcome, cost).

    The new configuration lies ``step`` (chordal) along the local path, or is the target if
    closer; its alphas are repaired (warm start: the near node's alphas; ``caps``:
    :func:`repair_objective`'s) as ``repair`` says. REACHED means ``out`` equals the
    target. Where the new configuration is invalid and ``partial`` > 0, ``out`` is the last
    valid configuration towards it (:func:`advance_partial`); where it is valid but the
    motion to it is not, the outcome is BLOCKED and the caller chooses
    (:func:`reshape_first`, :func:`advance_partial`).
    """
    weights = model[4]
    scratch = work[-1]
    ea, eb = scratch[0, :EMBEDDING], scratch[1, :EMBEDDING]
    embed_into(near, weights, ea)
    embed_into(target, weights, eb)
    distance = 0.0
    for a in range(EMBEDDING):
        distance += (ea[a] - eb[a]) ** 2
    distance = math.sqrt(distance)
    reached = distance <= step
    interpolate_into(near, target, 1.0 if reached else step / distance, out)
    if repair == REPAIR or (repair == REPAIR_UNLESS_REACHED and not reached):
        reached = False
        value, cost = _choose_alphas(near, target, out, model, work, scratch[2], caps)
        if not value < math.inf:
            return FAILED, math.inf
        # the repair ends at a configuration it has checked: valid, of known cost
        cost, valid = repair_alphas(out, model, work, scratch[2], caps, value, cost), True
    else:
        cost, valid = state_check(out, model, work, True)
    if valid:
        if motion_check(near, out, resolution, model, work, True, False, False):
            return (REACHED if reached else ADVANCED), cost
        return BLOCKED, cost
    if partial > 0.0:
        cost = advance_partial(near, out, partial, resolution, model, work)
        if cost < math.inf:
            return ADVANCED, cost
    return FAILED, math.inf


@kernel()
def advance_partial(near, out, least, resolution, model, work) -> float:
    """Move ``out`` back along the local path near -> out to its last valid configuration
    (at the motion's discretization); that configuration's cost if it lies at least
    ``least`` (path length) from near and the motion to it is valid, else +inf and ``out``
    means nothing. Where a passage is narrower than the step, the part of an extension
    that fits is progress the full step would lose."""
    weights = model[4]
    length = geodesic_length(near, out, weights[0], weights[1])
    t = motion_last_valid(near, out, resolution, model, work, True)
    if t * length < least:
        return math.inf
    end = work[-1][2, :9]
    for k in range(9):
        end[k] = out[k]
    interpolate_into(near, end, t, out)
    cost, valid = state_check(out, model, work, True)
    # The shorter motion is discretized at other points: check it as every motion is.
    if not (valid and motion_check(near, out, resolution, model, work, True, False, False)):
        return math.inf
    return cost


@kernel()
def reshape_first(near, new, resolution, model, work, middle) -> float:
    """The two motions near -> middle -> new, where middle is the near pose with new's
    alphas: the formation changes in place, then the pose moves. Returns middle's cost if
    middle and both motions are valid, else +inf. Where a passage only fits another
    formation (a corridor), the straight motion enters it still reshaping; this one
    reshapes before it moves."""
    for k in range(9):
        middle[k] = near[k] if k < 6 else new[k]
    cost, valid = state_check(middle, model, work, True)
    if not (
        valid
        and motion_check(near, middle, resolution, model, work, True, False, False)
        and motion_check(middle, new, resolution, model, work, True, False, False)
    ):
        return math.inf
    return cost
