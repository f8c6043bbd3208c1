"""Width of a Puzzle variant's threading passage in the (x, z, tilt) slice.

    python benchmarks/puzzle_passage.py --variant '{"slab": 0.1, "hole": [1.4, 0.6],
        "spacing": 1.0, "long_bar": 1.6, "start_z": 7.0}' --margins 0.1 0.15 0.2

A breadth-first search on a grid over (x, z, theta) at y = 0, phi = sigma = 0 (tilting about
y), with the cost-optimal alphas of each tilt, from the start's height to a level pose over
the hole with the long bar below the slab and the short bar above it. It runs against the
slab inflated by each margin (thicker, hole smaller on every side), so the largest margin
with a path is the passage's clearance in this slice; ``--max-tilt`` bounds the tilt, so
the smallest bound with a path is the tilt the passage needs. The slice ignores y, the
tilt-axis/torsion alignment and the alphas, where the 9-D passage is narrower: BENCHMARKS.md
("Puzzle: calibration and Table I") records both.
"""

from __future__ import annotations

import argparse
import json
from collections import deque
from pathlib import Path

import numpy as np
from puzzle_calibration import SLAB_BOTTOM, puzzle_variant
from scipy.optimize import minimize

from flycrane.planning.problem import PlanningProblem

UPPER_BAR_BELOW_P = 1.1  #: puzzle.toml: the upper bar's centre below P [m]
BAR_HALF = 0.04  #: half the bars' square section [m]


def best_alphas(problem: PlanningProblem, tilts: np.ndarray) -> np.ndarray:
    """Alphas of least cost at each tilt (about y, level elsewhere), warm-started in order."""
    out, guess = [], np.ones(3)
    for theta in tilts:

        def log_cost(a, theta=theta):
            return float(np.log(problem.validity.cost([[0, 0, 5, 0, theta, 0, *a]])[0]))

        result = minimize(log_cost, guess, method="Nelder-Mead", options={"xatol": 1e-3})
        guess = result.x
        out.append(result.x)
    return np.array(out)


def slice_path(
    variant: dict, margin: float, max_tilt: float, grid: float = 0.04
) -> np.ndarray | None:
    """Configurations (M, 9) of the BFS path through the inflated variant, from the
    start's grid cell to a level cell over the hole, or None if there is none."""
    inflated = dict(variant)
    slab = variant.get("slab", 0.2)
    hole = variant.get("hole", (1.1, 0.5))
    inflated["slab"] = slab + 2 * margin
    inflated["hole"] = (hole[0] - 2 * margin, hole[1] - 2 * margin)
    problem = PlanningProblem.from_scene(puzzle_variant(**inflated, bounds={"max_tilt": 1.0}))
    xs = np.arange(-3.0, 1.2, grid)
    zs = np.arange(SLAB_BOTTOM + 0.3, problem.start[2] + 0.3, grid)
    tilts = np.arange(0.0, max_tilt + 1e-9, grid / 2)
    alphas = best_alphas(problem, tilts)
    x, z, t = np.meshgrid(xs, zs, np.arange(len(tilts)), indexing="ij")
    q = np.zeros((*x.shape, 9))
    q[..., 0], q[..., 2], q[..., 4], q[..., 6:] = x, z, tilts[t], alphas[t]
    ok = problem.validity.is_valid(q.reshape(-1, 9)).reshape(x.shape)
    slab_top = SLAB_BOTTOM + slab + margin  # top of the inflated slab
    lower_below_p = UPPER_BAR_BELOW_P + variant.get("spacing", 0.5)
    targets = {
        (i, j, 0)
        for i in range(len(xs))
        for j in range(len(zs))
        if ok[i, j, 0]
        and abs(xs[i]) < 0.3
        and zs[j] - lower_below_p + BAR_HALF < SLAB_BOTTOM - margin
        and zs[j] - UPPER_BAR_BELOW_P - BAR_HALF > slab_top
    }
    start_x, start_z = problem.start[0], problem.start[2]
    first = (int(np.argmin(abs(xs - start_x))), int(np.argmin(abs(zs - start_z))), 0)
    if not ok[first]:
        return None
    previous = {first: None}
    queue = deque([first])
    while queue:
        node = queue.popleft()
        if node in targets:
            cells = []
            while node is not None:
                cells.append(node)
                node = previous[node]
            return np.array([q[cell] for cell in reversed(cells)])
        for axis in range(3):
            for step in (-1, 1):
                near = list(node)
                near[axis] += step
                key = tuple(near)
                if 0 <= near[axis] < ok.shape[axis] and ok[key] and key not in previous:
                    previous[key] = node
                    queue.append(key)
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", type=json.loads, default={})
    parser.add_argument("--margins", type=float, nargs="+", default=[0.0])
    parser.add_argument("--max-tilt", type=float, default=0.6)
    parser.add_argument(
        "--witness", type=Path, help="write the path found at the first margin as a witness"
    )
    args = parser.parse_args()
    for margin in args.margins:
        path = slice_path(args.variant, margin, args.max_tilt)
        found = "no path" if path is None else f"path of {len(path)} grid cells"
        print(f"variant {args.variant} margin {margin} m, tilt <= {args.max_tilt}: {found}")
        if args.witness and margin == args.margins[0] and path is not None:
            write_witness(args.variant, margin, path, args.witness)


def write_witness(variant: dict, margin: float, cells: np.ndarray, out: Path) -> None:
    """The slice path as a witness: start, the grid path with straight runs merged, a
    vertical descent to the goal; every motion checked against the real (not inflated)
    variant at the planner's motion resolution."""
    problem = PlanningProblem.from_scene(puzzle_variant(**variant))
    corners = [cells[0]]
    for before, here, after in zip(cells[:-2], cells[1:-1], cells[2:], strict=True):
        if not np.allclose(here - before, after - here):
            corners.append(here)
    corners.append(cells[-1])
    over_goal = problem.goal.copy()
    over_goal[6:] = cells[-1][6:]  # descend at the slice's alphas, then hover as the goal
    path = np.array([problem.start, *corners, over_goal, problem.goal])
    valid = problem.validity.motion_is_valid
    bad = [i for i in range(len(path) - 1) if not valid(path[i], path[i + 1])]
    if bad:
        raise SystemExit(f"witness motions {bad} are invalid in the real scene")
    description = (
        f"A valid path for the Puzzle variant {json.dumps(variant)}: a breadth-first search "
        f"on a {len(cells)}-cell (x, z, tilt) grid path at y = 0, tilting about y, with "
        f"least-cost alphas, against the slab inflated by {margin} m beyond the scene's "
        f"obstacle clearance ({problem.scene.collision.obstacle_clearance} m) "
        "(benchmarks/puzzle_passage.py --witness), straight runs merged, then a vertical "
        "descent to the goal. Every motion is valid at the planner's motion resolution."
    )
    out.write_text(json.dumps({"description": description, "path": path.tolist()}, indent=1))
    print(f"witness of {len(path)} configurations written to {out}")


if __name__ == "__main__":
    main()
