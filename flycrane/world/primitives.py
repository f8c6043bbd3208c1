"""Compiled (numba) distance tests between convex primitives: the fast collision path.

A shape is a convex *core* plus a margin: a sphere is a point with its radius, a capsule a
segment with its radius, and boxes, cylinders and convex polytopes (the platform's prism)
are their own cores with margin 0. Two shapes touch iff the distance between their cores is
at most the sum of their margins.

:func:`separated` answers that with GJK (Gilbert, Johnson, Keerthi 1988) on the cores'
Minkowski difference D = A - B, iterating the closest point v of a simplex in D to the
origin (sub-simplex search as in Ericson, *Real-Time Collision Detection*, 2005, 5.1). It
decides from bounds, never from an estimate: for every w = s_D(-v) the plane through w
normal to v bounds D, so ``v.w / |v|`` is a lower bound of the distance and ``|v|`` an
upper bound. "Separated" is returned only when the lower bound exceeds the margin; when the
upper bound falls to the margin, the simplex encloses the origin, the bounds meet within
EPS_RELATIVE, or the iterations run out, the answer is "touching". So the test never calls
touching shapes free; it calls separated shapes touching only within a relative 1e-10 of
the margin (or within CONTACT_TOLERANCE of contact for margin-free pairs). Degenerate
simplices (coincident or collinear points) take their lower-dimensional faces; the kernels
use numpy's error model, so no arithmetic raises, and a NaN fails every bound test and ends
as "touching".

Shapes are rows of tables (centres (n, 3), rotations (n, 3, 3), sizes (n, 3), vertices
(V, 3)), world frame, passed with their kind and row index (indexing whole tables, not
slicing views, keeps the compiled calls free of reference counting): POINT at its centre;
SEGMENT from its centre to its ``size`` row; BOX centre, axes (columns of the rotation),
half sizes; CYLINDER centre, axes (its own z is the axis), size = (radius, half height, -);
POLYTOPE the convex hull of the vertices; TRIANGLE (a mesh's face) its three corners, the
rows of its rotation slot (its centre row holds their centroid).
"""

from __future__ import annotations

import math

from flycrane.kernels import kernel

POINT, SEGMENT, BOX, CYLINDER, POLYTOPE, TRIANGLE = 0, 1, 2, 3, 4, 5

#: GJK stops, calling the shapes touching, when its bounds meet to this relative gap.
EPS_RELATIVE = 1e-10
#: Distances below this [m] count as contact for shapes without a margin (boxes against
#: boxes): GJK's closest point reaches the origin only to rounding.
CONTACT_TOLERANCE = 1e-9
#: Rows of the (GJK_WORK, 3) scratch of :func:`separated`: simplex (4), v, w, two support
#: points, a closest-point candidate, and 3 rows to compact the simplex through.
GJK_WORK = 12
#: Iteration cap; polytopes converge in a few steps, curved cores well within it.
MAX_ITERATIONS = 64


@kernel(error_model="numpy")
def support(kind, row, centers, rots, sizes, verts, dx, dy, dz, out) -> None:
    """The point of shape ``row`` of a table furthest along (dx, dy, dz), into out (3,)."""
    if kind == POINT:
        out[0], out[1], out[2] = centers[row, 0], centers[row, 1], centers[row, 2]
    elif kind == SEGMENT:
        a = centers[row, 0] * dx + centers[row, 1] * dy + centers[row, 2] * dz
        b = sizes[row, 0] * dx + sizes[row, 1] * dy + sizes[row, 2] * dz
        end = centers if a >= b else sizes
        out[0], out[1], out[2] = end[row, 0], end[row, 1], end[row, 2]
    elif kind == BOX or kind == CYLINDER:
        lx = rots[row, 0, 0] * dx + rots[row, 1, 0] * dy + rots[row, 2, 0] * dz
        ly = rots[row, 0, 1] * dx + rots[row, 1, 1] * dy + rots[row, 2, 1] * dz
        lz = rots[row, 0, 2] * dx + rots[row, 1, 2] * dy + rots[row, 2, 2] * dz
        if kind == BOX:
            px = sizes[row, 0] if lx >= 0.0 else -sizes[row, 0]
            py = sizes[row, 1] if ly >= 0.0 else -sizes[row, 1]
            pz = sizes[row, 2] if lz >= 0.0 else -sizes[row, 2]
        else:
            radial = math.sqrt(lx * lx + ly * ly)
            px = sizes[row, 0] * lx / radial if radial > 0.0 else 0.0
            py = sizes[row, 0] * ly / radial if radial > 0.0 else 0.0
            pz = sizes[row, 1] if lz >= 0.0 else -sizes[row, 1]
        for a in range(3):
            out[a] = (
                centers[row, a] + rots[row, a, 0] * px + rots[row, a, 1] * py + rots[row, a, 2] * pz
            )
    elif kind == TRIANGLE:
        best, index = -math.inf, 0
        for k in range(3):
            value = rots[row, k, 0] * dx + rots[row, k, 1] * dy + rots[row, k, 2] * dz
            if value > best:
                best, index = value, k
        out[0], out[1], out[2] = rots[row, index, 0], rots[row, index, 1], rots[row, index, 2]
    else:
        best, index = -math.inf, 0
        for k in range(verts.shape[0]):
            value = verts[k, 0] * dx + verts[k, 1] * dy + verts[k, 2] * dz
            if value > best:
                best, index = value, k
        out[0], out[1], out[2] = verts[index, 0], verts[index, 1], verts[index, 2]


@kernel(error_model="numpy")
def bounds(kind, row, centers, rots, sizes, verts, margin, out, out_row) -> None:
    """Axis-aligned bounds of shape ``row`` grown by ``margin``: out[out_row, 0] the low
    corner, out[out_row, 1] the high one (exact for every kind)."""
    for a in range(3):
        if kind == POINT:
            low = high = centers[row, a]
        elif kind == SEGMENT:
            low = min(centers[row, a], sizes[row, a])
            high = max(centers[row, a], sizes[row, a])
        elif kind == BOX:
            half = (
                abs(rots[row, a, 0]) * sizes[row, 0]
                + abs(rots[row, a, 1]) * sizes[row, 1]
                + abs(rots[row, a, 2]) * sizes[row, 2]
            )
            low, high = centers[row, a] - half, centers[row, a] + half
        elif kind == CYLINDER:
            axis = rots[row, a, 2]
            half = sizes[row, 0] * math.sqrt(max(0.0, 1.0 - axis * axis)) + sizes[row, 1] * abs(
                axis
            )
            low, high = centers[row, a] - half, centers[row, a] + half
        elif kind == TRIANGLE:
            low = min(rots[row, 0, a], rots[row, 1, a], rots[row, 2, a])
            high = max(rots[row, 0, a], rots[row, 1, a], rots[row, 2, a])
        else:
            low, high = math.inf, -math.inf
            for k in range(verts.shape[0]):
                low, high = min(low, verts[k, a]), max(high, verts[k, a])
        out[out_row, 0, a] = low - margin
        out[out_row, 1, a] = high + margin


@kernel(error_model="numpy")
def _copy(source, target) -> None:
    """target[:] = source for 3-vectors, element by element (numba compiles an array
    assignment into seconds of broadcasting machinery; this into nothing)."""
    target[0], target[1], target[2] = source[0], source[1], source[2]


@kernel(error_model="numpy")
def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel(error_model="numpy")
def _squared_gap(a, b) -> float:
    return (b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2


@kernel(error_model="numpy")
def _segment_closest(a, b, v) -> float:
    """Closest point v of segment ab to the origin; returns its squared distance."""
    e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    length = e0 * e0 + e1 * e1 + e2 * e2
    t = 0.0
    if length > 0.0:
        t = min(1.0, max(0.0, -(e0 * a[0] + e1 * a[1] + e2 * a[2]) / length))
    v[0], v[1], v[2] = a[0] + t * e0, a[1] + t * e1, a[2] + t * e2
    return v[0] * v[0] + v[1] * v[1] + v[2] * v[2]


@kernel(error_model="numpy")
def _triangle(a, b, c, v, scratch) -> int:
    """Closest point v of triangle abc to the origin; returns the kept vertices as bits
    (1: a, 2: b, 4: c). Ericson 5.1.5 with p = 0; a degenerate triangle falls back to its
    edges."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1 = -(ab0 * a[0] + ab1 * a[1] + ab2 * a[2])
    d2 = -(ac0 * a[0] + ac1 * a[1] + ac2 * a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        v[0], v[1], v[2] = a[0], a[1], a[2]
        return 1
    d3 = -(ab0 * b[0] + ab1 * b[1] + ab2 * b[2])
    d4 = -(ac0 * b[0] + ac1 * b[1] + ac2 * b[2])
    if d3 >= 0.0 and d4 <= d3:
        v[0], v[1], v[2] = b[0], b[1], b[2]
        return 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3) if d1 > d3 else 0.0  # d1 = d3 = 0: a and b coincide
        v[0], v[1], v[2] = a[0] + t * ab0, a[1] + t * ab1, a[2] + t * ab2
        return 3
    d5 = -(ab0 * c[0] + ab1 * c[1] + ab2 * c[2])
    d6 = -(ac0 * c[0] + ac1 * c[1] + ac2 * c[2])
    if d6 >= 0.0 and d5 <= d6:
        v[0], v[1], v[2] = c[0], c[1], c[2]
        return 4
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6) if d2 > d6 else 0.0
        v[0], v[1], v[2] = a[0] + t * ac0, a[1] + t * ac1, a[2] + t * ac2
        return 5
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        span = (d4 - d3) + (d5 - d6)
        t = (d4 - d3) / span if span > 0.0 else 0.0
        v[0] = b[0] + t * (c[0] - b[0])
        v[1] = b[1] + t * (c[1] - b[1])
        v[2] = b[2] + t * (c[2] - b[2])
        return 6
    total = va + vb + vc
    if total <= 0.0:  # collinear corners: the nearest of the three edges
        kept = 3
        best = _segment_closest(a, b, v)
        if _segment_closest(a, c, scratch) < best:
            best, kept = _dot(scratch, scratch), 5
            v[0], v[1], v[2] = scratch[0], scratch[1], scratch[2]
        if _segment_closest(b, c, scratch) < best:
            kept = 6
            v[0], v[1], v[2] = scratch[0], scratch[1], scratch[2]
        return kept
    s, t = vb / total, vc / total
    v[0] = a[0] + s * ab0 + t * ac0
    v[1] = a[1] + s * ab1 + t * ac1
    v[2] = a[2] + s * ab2 + t * ac2
    return 7


@kernel(error_model="numpy")
def _closest_on_simplex(simplex, n, v, scratch, chosen) -> int:
    """Closest point v of the simplex (n points) to the origin; the simplex is reduced to
    the smallest face holding it. Returns the new size, 0 if the origin is inside."""
    if n == 1:
        _copy(simplex[0], v)
        return 1
    if n == 2:
        a, b = simplex[0], simplex[1]
        e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
        length = e0 * e0 + e1 * e1 + e2 * e2
        t = -(e0 * a[0] + e1 * a[1] + e2 * a[2]) / length if length > 0.0 else 0.0
        if t <= 0.0:
            _copy(a, v)
            return 1
        if t >= 1.0:
            _copy(b, v)
            _copy(b, simplex[0])
            return 1
        v[0], v[1], v[2] = a[0] + t * e0, a[1] + t * e1, a[2] + t * e2
        return 2
    if n == 3:
        bits = _triangle(simplex[0], simplex[1], simplex[2], v, scratch)
        return _keep(simplex, chosen, bits, 0, 1, 2)
    # Tetrahedron: the origin is inside unless it lies outside some face's plane; faces
    # (0, 1, 2), (0, 2, 3), (0, 3, 1), (1, 3, 2), each with its opposite corner.
    a, b, c, d = simplex[0], simplex[1], simplex[2], simplex[3]
    scale = math.sqrt(_squared_gap(a, b) * _squared_gap(a, c) * _squared_gap(a, d))
    best = math.inf
    face = -1
    for f in range(4):
        i = 1 if f == 3 else 0
        j = (1, 2, 3, 3)[f]
        k = (2, 3, 1, 2)[f]
        o = (3, 1, 2, 0)[f]
        distance = _face_distance(simplex, i, j, k, o, scale, scratch, chosen)
        if distance < best:
            best, face = distance, f
            _copy(scratch, v)
    if face < 0:
        return 0
    i = 1 if face == 3 else 0
    j = (1, 2, 3, 3)[face]
    k = (2, 3, 1, 2)[face]
    bits = _triangle(simplex[i], simplex[j], simplex[k], scratch, chosen[0])
    return _keep(simplex, chosen, bits, i, j, k)


@kernel(error_model="numpy")
def _face_distance(simplex, i, j, k, o, scale, v, scratch) -> float:
    """Squared distance from the origin to face ijk when the origin lies outside the face's
    plane (or the tetrahedron is flat), its closest point into v; +inf otherwise."""
    p, q, r, x = simplex[i], simplex[j], simplex[k], simplex[o]
    n0 = (q[1] - p[1]) * (r[2] - p[2]) - (q[2] - p[2]) * (r[1] - p[1])
    n1 = (q[2] - p[2]) * (r[0] - p[0]) - (q[0] - p[0]) * (r[2] - p[2])
    n2 = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    side_origin = -(n0 * p[0] + n1 * p[1] + n2 * p[2])
    side_opposite = n0 * (x[0] - p[0]) + n1 * (x[1] - p[1]) + n2 * (x[2] - p[2])
    flat = abs(side_opposite) <= 1e-12 * scale  # a degenerate tetrahedron: try every face
    if not (flat or side_origin * side_opposite < 0.0):
        return math.inf
    _triangle(p, q, r, v, scratch[0])
    return _dot(v, v)


@kernel(error_model="numpy")
def _keep(simplex, chosen, bits, i, j, k) -> int:
    """Compact simplex points i, j, k selected by bits (1, 2, 4) to the front (through
    ``chosen``, 3 x 3 scratch, as the indices may cross)."""
    n = 0
    if bits & 1:
        _copy(simplex[i], chosen[n])
        n += 1
    if bits & 2:
        _copy(simplex[j], chosen[n])
        n += 1
    if bits & 4:
        _copy(simplex[k], chosen[n])
        n += 1
    for m in range(n):
        _copy(chosen[m], simplex[m])
    return n


@kernel(error_model="numpy")
def separated(ka, ra, ca, rota, sa, va, kb, rb, cb, rotb, sb, vb, margin, work) -> bool:
    """True iff the cores are certainly more than ``margin`` apart (module docstring).
    ``work``: (GJK_WORK, 3) scratch, so that the test allocates nothing."""
    simplex, chosen = work[0:4], work[9:12]
    v, w, pa, pb, scratch = work[4], work[5], work[6], work[7], work[8]
    support(ka, ra, ca, rota, sa, va, 1.0, 0.0, 0.0, pa)
    support(kb, rb, cb, rotb, sb, vb, -1.0, 0.0, 0.0, pb)
    for a in range(3):
        v[a] = pa[a] - pb[a]
    _copy(v, simplex[0])
    n = 1
    limit = max(margin, CONTACT_TOLERANCE) ** 2
    for _ in range(MAX_ITERATIONS):
        vv = _dot(v, v)
        if vv <= limit:
            return False
        support(ka, ra, ca, rota, sa, va, -v[0], -v[1], -v[2], pa)
        support(kb, rb, cb, rotb, sb, vb, v[0], v[1], v[2], pb)
        for a in range(3):
            w[a] = pa[a] - pb[a]
        vw = _dot(v, w)
        if vw > 0.0 and vw * vw > margin * margin * vv:
            return True  # the lower bound v.w / |v| exceeds the margin
        if vv - vw <= EPS_RELATIVE * vv:
            return False  # converged with the lower bound at or below the margin
        _copy(w, simplex[n])
        n = _closest_on_simplex(simplex, n + 1, v, scratch, chosen)
        if n == 0:
            return False  # the origin is inside D: the cores overlap
    return False


@kernel(error_model="numpy")
def point_distance_squared(point, kind, row, centers, rots, sizes) -> float:
    """Squared distance from a point (3,) to the core of shape ``row`` of a table, for a
    point, a segment, a solid box or a solid cylinder (exact); -1 for other kinds."""
    if kind == POINT or kind == SEGMENT:
        r0 = point[0] - centers[row, 0]
        r1 = point[1] - centers[row, 1]
        r2 = point[2] - centers[row, 2]
        t = 0.0
        if kind == SEGMENT:
            e0 = sizes[row, 0] - centers[row, 0]
            e1 = sizes[row, 1] - centers[row, 1]
            e2 = sizes[row, 2] - centers[row, 2]
            length = e0 * e0 + e1 * e1 + e2 * e2
            if length > 0.0:
                t = min(1.0, max(0.0, (r0 * e0 + r1 * e1 + r2 * e2) / length))
            r0, r1, r2 = r0 - t * e0, r1 - t * e1, r2 - t * e2
        return r0 * r0 + r1 * r1 + r2 * r2
    if kind != BOX and kind != CYLINDER:
        return -1.0
    l0 = l1 = l2 = 0.0
    for a in range(3):
        d = point[a] - centers[row, a]
        l0 += rots[row, a, 0] * d
        l1 += rots[row, a, 1] * d
        l2 += rots[row, a, 2] * d
    if kind == BOX:
        e0 = max(0.0, abs(l0) - sizes[row, 0])
        e1 = max(0.0, abs(l1) - sizes[row, 1])
        e2 = max(0.0, abs(l2) - sizes[row, 2])
        return e0 * e0 + e1 * e1 + e2 * e2
    radial = max(0.0, math.sqrt(l0 * l0 + l1 * l1) - sizes[row, 0])
    axial = max(0.0, abs(l2) - sizes[row, 1])
    return radial * radial + axial * axial


@kernel(error_model="numpy")
def shapes_touch(ka, ra, ca, rota, sa, va, kb, rb, cb, rotb, sb, vb, margin, work) -> bool:
    """Whether the cores of shape ``ra`` of table a and shape ``rb`` of table b (each table:
    centres, rotations, sizes, vertices) are within ``margin``: closed forms for a point
    against a point, a segment, a box or a cylinder (exact), GJK (:func:`separated`) for
    every other pair."""
    if ka == POINT:
        d = point_distance_squared(ca[ra], kb, rb, cb, rotb, sb)
        if d >= 0.0:
            return d <= margin * margin
    elif kb == POINT:
        d = point_distance_squared(cb[rb], ka, ra, ca, rota, sa)
        if d >= 0.0:
            return d <= margin * margin
    return not separated(ka, ra, ca, rota, sa, va, kb, rb, cb, rotb, sb, vb, margin, work)
