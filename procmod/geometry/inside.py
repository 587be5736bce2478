"""Inside and outside of triangle meshes as modelling tools write them.

Meshes exported from Blender, Maya or a CAD tool are rarely clean closed surfaces: several
overlapping components, faces wound the wrong way, small holes, edges shared by three or
more faces. Ray parity (the voxelizer's rule for model parts) is wrong on all of these: a
voxel inside two overlapping components counts two crossings and comes out empty, and a
ray through a hole misses a crossing and fills or empties a whole column. Here a point is
inside when its **generalised winding number** (Jacobson, Kavan and Sorkine-Hornung 2013)

    w(p) = (1 / 4 pi) sum_t Omega_t(p)      (Omega_t: signed solid angle of triangle t at p)

is at least 1/2. For a closed, outward-facing surface w is 1 inside and 0 outside; for
overlapping components it counts how many contain p (still inside); across a small hole
it changes smoothly (about 1/2 in the hole) instead of flipping a column.

Computing it on a voxel grid, exactly and fast. Summing solid angles over every triangle
at every voxel costs voxels x faces (10^12 for a million faces on a 100^3 grid). Instead:

1. **Close the holes.** The mesh's boundary is the 1-chain of its directed edges with
   opposite edges cancelled (a hole's rim, a face wound against its neighbours, a dangling
   fin). It splits into closed walks, and each walk is spanned by a "cap" of triangles
   (:func:`cap_tree`); mesh plus caps is a closed chain, and ``w_mesh = w_closed - w_caps``.
2. **The closed part is a crossing count.** For a closed chain, w is the signed number of
   its triangles a ray from p crosses. :func:`closed_winding` sends one vertical line
   through each voxel column, collects its crossings once (a triangle touches only the
   columns its projection covers), and sweeps the column: O(faces + crossings + voxels).
   Ties (a line through an edge or a vertex) are broken by a symbolic perturbation of the
   line, with each edge evaluated in a canonical vertex order, so a line through an edge
   shared by two triangles counts it exactly once: the counts are exact integers.
3. **The caps only matter near the holes.** A surface of area A seen from distance d
   subtends at most A / d^2 of solid angle. Where the caps' bounds sum below 0.4 (in
   winding-number units, :data:`CAP_BOUND`), ``w >= 1/2`` is exactly ``w_closed >= 1``;
   whole 8^3 voxel blocks are settled so. In the blocks near a cap, each voxel sums the
   caps' solid angles over a tree (the cycles' caps under a bounding-volume tree), leaving
   out subtrees whose bound is below a tolerance and adding their bounds to an error; the
   tolerance shrinks (:data:`EPS_STEPS`) until the error cannot change the decision, and a
   voxel still undecided (within ~1e-6 of w = 1/2) sums every cap triangle. The decision
   is therefore that of the exact winding number (up to floating-point rounding), not an
   approximation.

A clean closed mesh costs one crossing sweep, and a mesh with small holes little more
(1.3 million faces on a 191^3 grid: about 1 s closed, 1.6 s with small holes, 4 s with
an open top of 1200 rim edges; 2 cores). Cost grows with (voxels near holes) x (rim edges
that cannot be bounded away): a mesh made mostly of open pieces (a soup of separate
triangles) costs the most, and :func:`inside_voxels` refuses one whose work, estimated
from a sample of voxels, exceeds :data:`MAX_CAP_WORK` steps.

Repeated faces. A face twice with the same winding (a piece duplicated in place) counts
twice; a face with its reverse (a model exported double-sided, SketchUp's back faces, the
shared wall of two solids that touch) counts nothing, so a closed model exported
double-sided has no inside at all. :func:`single_sided` keeps one of each repeated face,
takes such pairs out (the winding number of the rest is unchanged) and puts one copy back
of each piece they form that is closed: the double-sided model becomes its closed
surface, while a shared wall or a double-sided open sheet (a fin) stays out, as it added
nothing.

Orientation. Winding numbers need faces wound consistently. :func:`orient_faces` makes
every edge-connected component consistent (a breadth-first walk across edges shared by
exactly two faces, flipping a face whose shared edge runs the same way as its neighbour's)
and outward: a component enclosing negative volume is turned over, unless it lies inside
the other components (then it is a cavity, such as the inner wall of a hollow part, and is
kept facing in): the centroids of up to :data:`CAVITY_PROBES` of its faces, spread over it,
must all be inside; a flipped piece overlapping another only in part is turned over. An
outward piece wholly inside a piece that is turned over is turned over with it: it is that
piece's inner wall (a hollow part exported inside out, all its normals flipped).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..core.limits import ResourceLimitError

BLOCK = 8  # voxels per block side for the cap correction
CAP_BOUND = 0.4  # |w_caps| below this leaves the decision to the crossing count
# A voxel near a cap first evaluates the caps to within 0.05 (in winding-number units): if
# that cannot settle w >= 1/2, to within 0.005, ...; then exactly
EPS_STEPS = (0.05, 5e-3, 5e-4, 5e-5, 5e-6)
# Cap-tree node visits the hole correction may make: 3e7 to 1e8 a second on 2 cores, so
# up to some 20 s. A mesh that needs more is mostly open pieces (a soup of triangles).
MAX_CAP_WORK = 6e8
SAMPLE_VOXELS = 64  # voxels decided first, to estimate the work of the rest
CAVITY_TESTS = 16  # inward-facing components tested for being cavities (the largest first)
CAVITY_PROBES = 16  # faces of such a component that must all lie inside the outward ones


# --- winding numbers by direct summation (reference, and for a few points) ----------------

@numba.njit(cache=True, inline="always")
def _solid_angle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Signed solid angle of triangle (a, b, c) at p (Van Oosterom and Strackee 1983),
    positive when p lies behind it (on the side its normal (b - a) x (c - a) points away
    from): an outward-facing closed surface subtends +4 pi at the points inside it."""
    ax -= px
    ay -= py
    az -= pz
    bx -= px
    by -= py
    bz -= pz
    cx -= px
    cy -= py
    cz -= pz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
    den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la \
        + (cx * ax + cy * ay + cz * az) * lb
    return 2.0 * math.atan2(det, den)


@numba.njit(cache=True, parallel=True)
def _winding_direct(points, tris, weights, chunk):
    """w at each point by summing every triangle's solid angle; the work is split into
    (point, chunk of triangles) pieces so a few points over many triangles use every core."""
    n_chunks = (tris.shape[0] + chunk - 1) // chunk
    partial = np.zeros((points.shape[0], n_chunks))
    for piece in numba.prange(points.shape[0] * n_chunks):
        p, c = piece // n_chunks, piece % n_chunks
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        acc = 0.0
        for t in range(c * chunk, min((c + 1) * chunk, tris.shape[0])):
            acc += weights[t] * _solid_angle(px, py, pz, tris[t, 0, 0], tris[t, 0, 1], tris[t, 0, 2],
                                             tris[t, 1, 0], tris[t, 1, 1], tris[t, 1, 2],
                                             tris[t, 2, 0], tris[t, 2, 1], tris[t, 2, 2])
        partial[p, c] = acc
    return partial.sum(axis=1) / (4.0 * math.pi)


def winding_numbers(vertices, faces, points, weights=None) -> np.ndarray:
    """Generalised winding numbers of ``points`` (n, 3) with respect to the triangles
    ``vertices[faces]``, by direct summation (exact; cost points x faces)."""
    tris = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)])
    points = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    w = np.ones(len(tris)) if weights is None else np.asarray(weights, dtype=np.float64)
    if len(tris) == 0 or len(points) == 0:
        return np.zeros(len(points))
    return _winding_direct(points, tris, w, 4096)


# --- the closed part: signed crossings along voxel columns ---------------------------------

@numba.njit(cache=True, inline="always")
def _edge_side(ux, uy, vx, vy, qx, qy):
    """Sign (+1 / -1, never 0) of the orientation of (u, v, q'), q' = q + (eps, eps^2): q
    perturbed off every line, so no point lies on an edge. Evaluated with the endpoints in
    a canonical (lexicographic) order, so the edge gives the same value, negated, in the
    two triangles that share it."""
    flip = 1.0
    if vx < ux or (vx == ux and vy < uy):
        ux, uy, vx, vy = vx, vy, ux, uy
        flip = -1.0
    o = (vx - ux) * (qy - uy) - (vy - uy) * (qx - ux)
    if o == 0.0:
        # the perturbation's leading term: -(vy - uy) eps, else (vx - ux) eps^2
        o = -(vy - uy) if vy != uy else (vx - ux)
    return flip * (1.0 if o > 0.0 else -1.0), flip * ((vx - ux) * (qy - uy) - (vy - uy) * (qx - ux))


@numba.njit(cache=True)
def _triangle_columns(tris, weights, ox, oy, h, nx, ny, counts, col, zs, ss, fill):
    """Visit every (triangle, column) crossing: count them per column (``fill`` False) or
    write column index, height and signed weight at the column's next free slot."""
    for t in range(tris.shape[0]):
        if weights[t] == 0:
            continue
        ax, ay, az = tris[t, 0, 0], tris[t, 0, 1], tris[t, 0, 2]
        bx, by, bz = tris[t, 1, 0], tris[t, 1, 1], tris[t, 1, 2]
        cx, cy, cz = tris[t, 2, 0], tris[t, 2, 1], tris[t, 2, 2]
        x0, x1 = min(ax, bx, cx), max(ax, bx, cx)
        y0, y1 = min(ay, by, cy), max(ay, by, cy)
        fi0, fi1 = (x0 - ox) / h - 0.5, (x1 - ox) / h - 0.5  # the columns' indices it spans, as reals
        fj0, fj1 = (y0 - oy) / h - 0.5, (y1 - oy) / h - 0.5
        if not (fi1 > -1.0 and fi0 < nx and fj1 > -1.0 and fj0 < ny):
            continue  # clear of the grid's columns (or not finite): it crosses none
        # clamped before the int: past 2^63 (a stray face at 1e19) numba's int() is -2^63,
        # from which the loops below had counted up for ever
        i0 = max(int(math.ceil(max(fi0, -1.0))), 0)
        i1 = min(int(math.floor(min(fi1, float(nx)))), nx - 1)
        j0 = max(int(math.ceil(max(fj0, -1.0))), 0)
        j1 = min(int(math.floor(min(fj1, float(ny)))), ny - 1)
        # the division rounds: a column whose centre (computed as below) lies on the triangle's
        # bounds could be skipped (ox -2.7, h 0.2: centre 3 is at x = -2.0, but (-2.0 - ox) / h
        # - 0.5 is 3.000000000000001), losing the crossing its perturbed line makes there and
        # filling or emptying the whole column (a torus in OBJ lost a column through its tube)
        while i0 > 0 and ox + (i0 - 0.5) * h >= x0:
            i0 -= 1
        while i1 < nx - 1 and ox + (i1 + 1.5) * h <= x1:
            i1 += 1
        while j0 > 0 and oy + (j0 - 0.5) * h >= y0:
            j0 -= 1
        while j1 < ny - 1 and oy + (j1 + 1.5) * h <= y1:
            j1 += 1
        for i in range(i0, i1 + 1):
            qx = ox + (i + 0.5) * h
            for j in range(j0, j1 + 1):
                qy = oy + (j + 0.5) * h
                s0, e0 = _edge_side(ax, ay, bx, by, qx, qy)  # e0: area of (a, b, q), weight of c
                s1, e1 = _edge_side(bx, by, cx, cy, qx, qy)
                s2, e2 = _edge_side(cx, cy, ax, ay, qx, qy)
                if s0 != s1 or s1 != s2:
                    continue
                area = e0 + e1 + e2
                if area == 0.0:  # the line lies in a vertical triangle: no crossing
                    continue
                c = i * ny + j
                if fill:
                    slot = counts[c]
                    counts[c] += 1
                    zs[slot] = (e1 * az + e2 * bz + e0 * cz) / area
                    # counter-clockwise from above (s0 > 0) faces up: the downward ray from
                    # a point above it leaves through its back, -1; facing down, +1
                    ss[slot] = -weights[t] if s0 > 0 else weights[t]
                    col[slot] = c
                else:
                    counts[c] += 1


@numba.njit(cache=True)
def _sweep_columns(starts, zs, ss, oz, h, nz, out):
    """w_closed of every voxel: the signed crossings below its centre (``zs`` sorted within
    each column's range ``starts[c]:starts[c + 1]``). A crossing exactly
    at a centre counts when it is an entry (+), so a centre on the surface is inside, as
    the voxelizer's closed-interval rule for model parts has it."""
    for c in range(starts.shape[0] - 1):
        a, b = starts[c], starts[c + 1]
        base = c * nz
        if a == b:
            continue
        p, acc = a, 0
        for k in range(nz):
            zk = oz + (k + 0.5) * h
            while p < b and zs[p] < zk:
                acc += ss[p]
                p += 1
            extra = 0
            q = p
            while q < b and zs[q] == zk:
                if ss[q] > 0:
                    extra += ss[q]
                q += 1
            out[base + k] = acc + extra


def closed_winding(tris: np.ndarray, weights: np.ndarray, grid) -> np.ndarray:
    """Flat int32 signed crossing counts below every voxel centre of ``grid`` (index
    ``(i * ny + j) * nz + k``): the winding number of a closed chain of weighted triangles."""
    nx, ny, nz = (int(n) for n in grid.shape)
    ox, oy, oz = (float(v) for v in grid.origin)
    h = float(grid.size)
    tris = np.ascontiguousarray(tris, dtype=np.float64)
    weights = np.ascontiguousarray(weights, dtype=np.int64)
    counts = np.zeros(nx * ny, dtype=np.int64)
    dummy_f, dummy_i = np.zeros(0), np.zeros(0, dtype=np.int64)
    _triangle_columns(tris, weights, ox, oy, h, nx, ny, counts, dummy_i, dummy_f, dummy_i, False)
    starts = np.zeros(nx * ny + 1, dtype=np.int64)
    np.cumsum(counts, out=starts[1:])
    n = int(starts[-1])
    zs, ss, col = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    slots = starts[:-1].copy()
    _triangle_columns(tris, weights, ox, oy, h, nx, ny, slots, col, zs, ss, True)
    order = np.lexsort((zs, col))  # by column, then height (numpy's sort: numba compiles one slowly)
    zs, ss = zs[order], ss[order]
    out = np.zeros(nx * ny * nz, dtype=np.int32)
    _sweep_columns(starts, zs, ss, oz, h, nz, out)
    return out


# --- boundaries, caps, and the correction near them ---------------------------------------

def _half_edges(faces: np.ndarray):
    """Directed edges (a -> b) of every face, their undirected keys and a key order."""
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo.astype(np.int64) * (int(faces.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    return a, b, lo, hi, key, order


def boundary_chain(faces: np.ndarray):
    """The mesh's boundary as undirected edges ``(lo, hi)`` with integer coefficients: the
    number of faces running lo -> hi minus those running hi -> lo, where not zero (a hole's
    rim has +-1, an edge between a face and a neighbour wound the other way +-2). Faces
    with a repeated vertex bound nothing and are left out."""
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    if len(faces) == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    a, _, lo, hi, key, order = _half_edges(faces)
    sign = np.where(a == lo, 1, -1)
    sorted_key = key[order]
    first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    coeff = np.add.reduceat(sign[order], first)
    keep = coeff != 0
    idx = order[first[keep]]
    return np.stack([lo[idx], hi[idx]], axis=1), coeff[keep]


@numba.njit(cache=True)
def _trace_cycles(src, dst, n_vertices):
    """Split a directed edge multiset in which every vertex is entered as often as it is
    left into closed walks; returns (cycle start offsets, vertex sequence)."""
    m = src.shape[0]
    ptr = np.zeros(n_vertices + 1, dtype=np.int64)
    for e in range(m):
        ptr[src[e] + 1] += 1
    for v in range(n_vertices):
        ptr[v + 1] += ptr[v]
    out = np.empty(m, dtype=np.int64)  # edges grouped by their source vertex
    fill = ptr[:-1].copy()
    for e in range(m):
        out[fill[src[e]]] = e
        fill[src[e]] += 1
    nxt = ptr[:-1].copy()  # next out-edge of each vertex not yet walked
    starts = np.zeros(m + 1, dtype=np.int64)
    verts = np.empty(m, dtype=np.int64)
    used = np.zeros(m, dtype=np.bool_)
    n_cycles, n = 0, 0
    for k in range(m):
        e0 = out[k]
        if used[e0]:
            continue
        used[e0] = True
        start = src[e0]
        verts[n] = start
        n += 1
        cur = dst[e0]
        while cur != start:
            verts[n] = cur
            n += 1
            while used[out[nxt[cur]]]:
                nxt[cur] += 1
            e = out[nxt[cur]]
            used[e] = True
            nxt[cur] += 1
            cur = dst[e]
        n_cycles += 1
        starts[n_cycles] = n
    return starts[:n_cycles + 1], verts


@numba.njit(cache=True)
def _build_cap_tree(pos, starts, verts, tri, lo, hi, area, child, has_tri, cycle_root):
    """The cap of each boundary cycle as a binary tree of triangles (see cap_tree); returns
    the number of nodes written."""
    n_nodes = 0
    stack = np.empty((128, 3), dtype=np.int64)  # (i, j, parent) of runs still to build
    for c in range(starts.shape[0] - 1):
        a, b = starts[c], starts[c + 1]
        n = b - a
        root = n_nodes
        cycle_root[c] = root
        stack[0, 0], stack[0, 1], stack[0, 2] = 0, n, -1  # the root spans the cycle (v_n is v_0)
        depth = 1
        while depth > 0:
            depth -= 1
            i, j, parent = stack[depth, 0], stack[depth, 1], stack[depth, 2]
            node = n_nodes
            n_nodes += 1
            if parent >= 0:
                child[parent, 0 if child[parent, 0] < 0 else 1] = node
            m = (i + j) // 2
            vi, vm, vj = verts[a + i], verts[a + m], verts[a + (j % n)]
            for d in range(3):
                # wound (v_i, v_j, v_m), against the run: the cap's boundary cancels the mesh's
                tri[node, 0, d] = pos[vi, d]
                tri[node, 1, d] = pos[vj, d]
                tri[node, 2, d] = pos[vm, d]
                lo[node, d] = np.inf
                hi[node, d] = -np.inf
            for k in range(i, j + 1):
                v = verts[a + (k % n)]
                for d in range(3):
                    lo[node, d] = min(lo[node, d], pos[v, d])
                    hi[node, d] = max(hi[node, d], pos[v, d])
            has_tri[node] = parent >= 0  # the root's (v_0, v_0, v_m) is degenerate
            if has_tri[node]:
                ux, uy, uz = (tri[node, 1, 0] - tri[node, 0, 0], tri[node, 1, 1] - tri[node, 0, 1],
                              tri[node, 1, 2] - tri[node, 0, 2])
                wx, wy, wz = (tri[node, 2, 0] - tri[node, 0, 0], tri[node, 2, 1] - tri[node, 0, 1],
                              tri[node, 2, 2] - tri[node, 0, 2])
                nx_, ny_, nz_ = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
                area[node] = 0.5 * math.sqrt(nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
            if m - i >= 2:
                stack[depth, 0], stack[depth, 1], stack[depth, 2] = i, m, node
                depth += 1
            if j - m >= 2:
                stack[depth, 0], stack[depth, 1], stack[depth, 2] = m, j, node
                depth += 1
        for node in range(n_nodes - 1, root - 1, -1):  # subtree sums: children come after parents
            for s in range(2):
                ch = child[node, s]
                if ch >= 0:
                    area[node] += area[ch]
    return n_nodes


def _build_top_tree(cycle_root, lo, hi, area, child, n_nodes):
    """A bounding-volume tree over the cycles' caps (split at the median of the longer
    axis), so that a voxel far from a group of holes meets the group once. Returns the
    global root and the number of nodes. (Plain Python: one step per cycle, and numba
    compiles a sort over index ranges slowly.)"""
    n = len(cycle_root)
    if n == 1:
        return int(cycle_root[0]), n_nodes
    centre = 0.5 * (lo[cycle_root] + hi[cycle_root])
    first_top = n_nodes
    stack = [(np.arange(n), -1)]
    while stack:
        ids, parent = stack.pop()
        if len(ids) == 1:
            node = int(cycle_root[ids[0]])
        else:
            node = n_nodes
            n_nodes += 1
            c = centre[ids]
            axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
            ids = ids[np.argsort(c[:, axis], kind="stable")]
            half = len(ids) // 2
            stack += [(ids[half:], node), (ids[:half], node)]
        if parent >= 0:
            child[parent, 0 if child[parent, 0] < 0 else 1] = node
    top = np.arange(n_nodes - 1, first_top - 1, -1)
    for node in top:  # children are later top nodes or cycle roots: sum from the end
        a, b = child[node]
        area[node] = area[a] + area[b]
        lo[node] = np.minimum(lo[a], lo[b])
        hi[node] = np.maximum(hi[a], hi[b])
    return first_top, n_nodes


def cap_tree(vertices: np.ndarray, edges: np.ndarray, coeff: np.ndarray) -> dict:
    """Caps closing a boundary chain, as one tree of triangles.

    The chain is split into closed walks (cycles) v_0 -> v_1 -> ... -> v_0 (an edge of
    coefficient c is walked |c| times). A run v_i .. v_j of a cycle together with its chord
    v_j -> v_i is spanned by the triangle (v_i, v_m, v_j), m = (i + j) // 2, and the spans
    of the runs i..m and m..j: so the cap of a cycle of n edges is n - 2 triangles in a
    balanced binary tree. Deep nodes are thin slivers along the rim, of small area. The
    cycles' trees hang under a bounding-volume tree over the cycles. Every node holds its
    triangle (if any), the bounding box and the area of its subtree: what
    :func:`inside_voxels` needs to bound a subtree's solid angle (area / distance^2).

    Returns a dict of node arrays: ``tri`` (m, 3, 3), wound so that mesh plus caps is
    closed; ``has_tri``; ``lo``, ``hi``; ``area``; ``child`` (m, 2), -1 for none;
    and ``root``.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    coeff = np.asarray(coeff, dtype=np.int64)
    reps = np.abs(coeff)
    forward = np.repeat(coeff > 0, reps)
    e = np.repeat(edges, reps, axis=0)
    src = np.ascontiguousarray(np.where(forward, e[:, 0], e[:, 1]), dtype=np.int64)
    dst = np.ascontiguousarray(np.where(forward, e[:, 1], e[:, 0]), dtype=np.int64)
    starts, verts = _trace_cycles(src, dst, len(vertices))
    n_cycles = len(starts) - 1
    m = len(verts) + n_cycles
    tri = np.zeros((m, 3, 3))
    lo, hi = np.zeros((m, 3)), np.zeros((m, 3))
    area = np.zeros(m)
    child = np.full((m, 2), -1, dtype=np.int64)
    has_tri = np.zeros(m, dtype=np.bool_)
    roots = np.zeros(n_cycles, dtype=np.int64)
    n = _build_cap_tree(np.ascontiguousarray(vertices, dtype=np.float64), starts, verts, tri, lo, hi, area,
                        child, has_tri, roots)
    root, n = _build_top_tree(roots, lo, hi, area, child, n)
    return {"tri": tri[:n], "has_tri": has_tri[:n], "lo": lo[:n], "hi": hi[:n], "area": area[:n],
            "child": child[:n], "root": int(root), "cycles": n_cycles}


@numba.njit(cache=True)
def _cap_winding(px, py, pz, root, tri, has_tri, lo, hi, area, child, eps, stack, count):
    """w of the caps at p, and a bound on its error: a subtree whose solid angle is bounded
    (area / distance^2, in winding-number units) below ``eps`` is left out and its bound
    added to the error. ``eps`` 0: every triangle, exactly."""
    acc, err = 0.0, 0.0
    inv4pi = 1.0 / (4.0 * math.pi)
    stack[0] = root
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        count[0] += 1
        if eps > 0.0:
            gx = max(lo[node, 0] - px, 0.0, px - hi[node, 0])
            gy = max(lo[node, 1] - py, 0.0, py - hi[node, 1])
            gz = max(lo[node, 2] - pz, 0.0, pz - hi[node, 2])
            d2 = gx * gx + gy * gy + gz * gz
            if d2 > 0.0:
                bound = area[node] / d2 * inv4pi
                if bound < eps:
                    err += bound
                    continue
        if has_tri[node]:
            acc += _solid_angle(px, py, pz, tri[node, 0, 0], tri[node, 0, 1], tri[node, 0, 2],
                                tri[node, 1, 0], tri[node, 1, 1], tri[node, 1, 2],
                                tri[node, 2, 0], tri[node, 2, 1], tri[node, 2, 2]) * inv4pi
        for s in range(2):
            if child[node, s] >= 0:
                stack[top] = child[node, s]
                top += 1
    return acc, err


@numba.njit(cache=True)
def _decide(px, py, pz, closed, root, tri, has_tri, lo, hi, area, child, eps_steps, stack, count):
    """w_closed - w_caps >= 1/2 at p: w_caps is evaluated to the tolerances in ``eps_steps``
    in turn until its error bound cannot change the decision; a point still undecided
    (within about 1e-6 of w = 1/2) is summed over every cap triangle, exactly."""
    for eps in eps_steps:
        w_caps, err = _cap_winding(px, py, pz, root, tri, has_tri, lo, hi, area, child, eps, stack, count)
        w = closed - w_caps
        if abs(w - 0.5) > err:
            return w >= 0.5
    w_caps, _ = _cap_winding(px, py, pz, root, tri, has_tri, lo, hi, area, child, 0.0, stack, count)
    return closed - w_caps >= 0.5


@numba.njit(cache=True, parallel=True)
def _correct_blocks(inside, closed, blocks, root, tri, has_tri, lo, hi, area, child, ox, oy, oz, h,
                    nx, ny, nz, bs, eps_steps):
    """:func:`_decide` at every voxel of the listed blocks; returns the tree-node visits per block."""
    visits = np.zeros(blocks.shape[0], dtype=np.int64)
    for bi in numba.prange(blocks.shape[0]):
        stack = np.empty(512, dtype=np.int64)
        count = np.zeros(1, dtype=np.int64)
        i0, j0, k0 = blocks[bi, 0] * bs, blocks[bi, 1] * bs, blocks[bi, 2] * bs
        for i in range(i0, min(i0 + bs, nx)):
            for j in range(j0, min(j0 + bs, ny)):
                for k in range(k0, min(k0 + bs, nz)):
                    v = (i * ny + j) * nz + k
                    inside[v] = _decide(ox + (i + 0.5) * h, oy + (j + 0.5) * h, oz + (k + 0.5) * h, closed[v],
                                        root, tri, has_tri, lo, hi, area, child, eps_steps, stack, count)
        visits[bi] = count[0]
    return visits


@numba.njit(cache=True)
def _sample_visits(points, closed, root, tri, has_tri, lo, hi, area, child, eps_steps):
    """Tree-node visits :func:`_decide` makes at each point (to estimate the work)."""
    visits = np.zeros(points.shape[0], dtype=np.int64)
    for p in range(points.shape[0]):
        stack = np.empty(512, dtype=np.int64)
        count = np.zeros(1, dtype=np.int64)
        _decide(points[p, 0], points[p, 1], points[p, 2], closed[p], root, tri, has_tri, lo, hi, area, child,
                eps_steps, stack, count)
        visits[p] = count[0]
    return visits


@numba.njit(cache=True)
def _flag_blocks(blo, bhi, root, has_tri, lo, hi, area, child, limit):
    """True for the blocks where the caps may subtend |w| >= ``limit`` at some voxel centre
    (a bound: subtrees are expanded until their area / distance^2 bounds, summed, settle it)."""
    flagged = np.zeros(blo.shape[0], dtype=np.bool_)
    inv4pi = 1.0 / (4.0 * math.pi)
    stack = np.empty(512, dtype=np.int64)
    for b in range(blo.shape[0]):
        stack[0] = root
        top = 1
        total = 0.0
        while top > 0 and total < limit:
            top -= 1
            node = stack[top]
            gx = max(lo[node, 0] - bhi[b, 0], 0.0, blo[b, 0] - hi[node, 0])
            gy = max(lo[node, 1] - bhi[b, 1], 0.0, blo[b, 1] - hi[node, 1])
            gz = max(lo[node, 2] - bhi[b, 2], 0.0, blo[b, 2] - hi[node, 2])
            d2 = gx * gx + gy * gy + gz * gz
            bound = area[node] / d2 * inv4pi if d2 > 0.0 else np.inf
            if bound < 0.01 * limit:
                total += bound
                continue
            if has_tri[node]:  # its own triangle: bounded like the subtree, and by 1/2
                total += min(bound, 0.5)
            for s in range(2):
                if child[node, s] >= 0:
                    stack[top] = child[node, s]
                    top += 1
        flagged[b] = total >= limit
    return flagged


def _block_boxes(grid):
    """Block indices and each block's box of voxel centres (lo, hi), shape (nb, 3)."""
    shape = np.asarray(grid.shape, dtype=np.int64)
    nb = -(-shape // BLOCK)
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in nb], indexing="ij"), axis=-1).reshape(-1, 3)
    origin, h = np.asarray(grid.origin, dtype=np.float64), float(grid.size)
    lo = origin + (idx * BLOCK + 0.5) * h
    hi = origin + (np.minimum(idx * BLOCK + BLOCK, shape) - 0.5) * h
    return idx, lo, hi


def inside_voxels(vertices, faces, grid, what: str = "the mesh") -> np.ndarray:
    """Boolean ``grid.shape`` array: voxel centres whose generalised winding number with
    respect to the mesh is at least 1/2 (see the module docstring). Faces should be
    oriented (:func:`orient_faces`). Raises ResourceLimitError (naming ``what``) when the
    hole correction would need more than :data:`MAX_CAP_WORK` tree-node visits (estimated
    from a sample of the blocks it has to correct)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    shape = tuple(int(n) for n in grid.shape)
    if len(faces) == 0:
        return np.zeros(shape, dtype=bool)
    edges, coeff = boundary_chain(faces)
    tris = vertices[faces]
    if len(edges) == 0:
        return (closed_winding(tris, np.ones(len(tris), dtype=np.int64), grid) >= 1).reshape(shape)
    tree = cap_tree(vertices, edges, coeff)
    caps = tree["tri"][tree["has_tri"]]
    closed = closed_winding(np.concatenate([tris, caps]), np.ones(len(tris) + len(caps), dtype=np.int64), grid)
    inside = closed >= 1
    idx, blo, bhi = _block_boxes(grid)
    args = (tree["root"], tree["tri"], tree["has_tri"], tree["lo"], tree["hi"], tree["area"], tree["child"])
    blocks = idx[_flag_blocks(blo, bhi, tree["root"], tree["has_tri"], tree["lo"], tree["hi"], tree["area"],
                              tree["child"], CAP_BOUND)]
    if len(blocks) == 0:
        return inside.reshape(shape)
    eps_steps = np.asarray(EPS_STEPS)
    # the work, estimated from voxels spread over the blocks to correct (a fixed sample:
    # the same mesh and grid give the same estimate)
    pick = np.linspace(0, len(blocks) * BLOCK ** 3 - 1, min(SAMPLE_VOXELS, len(blocks) * BLOCK ** 3)).astype(np.int64)
    cell = blocks[pick // BLOCK ** 3] * BLOCK + np.stack([pick // BLOCK ** 2 % BLOCK, pick // BLOCK % BLOCK,
                                                          pick % BLOCK], axis=1)
    cell = cell[(cell < np.asarray(shape)).all(axis=1)]
    if len(cell):
        points = np.asarray(grid.origin) + (cell + 0.5) * float(grid.size)
        flat = (cell[:, 0] * shape[1] + cell[:, 1]) * shape[2] + cell[:, 2]
        visits = _sample_visits(points, closed[flat].astype(np.float64), *args, eps_steps)
        estimate = float(visits.mean()) * len(blocks) * BLOCK ** 3
        if estimate > MAX_CAP_WORK:
            raise ResourceLimitError(
                f"{what} has {len(edges):,} open edges in {tree['cycles']:,} boundary loops (holes, or faces not "
                f"joined to their neighbours); deciding its inside near them on a {'x'.join(map(str, shape))} grid "
                f"would take about {estimate:.1e} steps (procmod's limit is {MAX_CAP_WORK:.0e}): "
                "close the holes or join the pieces in a modelling tool, or use a larger voxel_size")
    _correct_blocks(inside, closed, blocks, *args, float(grid.origin[0]), float(grid.origin[1]), float(grid.origin[2]),
                    float(grid.size), shape[0], shape[1], shape[2], BLOCK, eps_steps)
    return inside.reshape(shape)


# --- orientation ---------------------------------------------------------------------------

@numba.njit(cache=True)
def _walk(n_faces, ptr, nbr, rel):
    """Breadth-first over face adjacency: component label and flip parity of every face."""
    comp = np.full(n_faces, -1, dtype=np.int64)
    parity = np.zeros(n_faces, dtype=np.int64)
    queue = np.empty(n_faces, dtype=np.int64)
    c = 0
    for start in range(n_faces):
        if comp[start] >= 0:
            continue
        comp[start] = c
        head, tail = 0, 1
        queue[0] = start
        while head < tail:
            f = queue[head]
            head += 1
            for e in range(ptr[f], ptr[f + 1]):
                g = nbr[e]
                if comp[g] < 0:
                    comp[g] = c
                    parity[g] = parity[f] ^ rel[e]
                    queue[tail] = g
                    tail += 1
        c += 1
    return comp, parity, c


@numba.njit(cache=True)
def _adjacency(n_faces, f1, f2, rel):
    """CSR face adjacency (both directions) from face pairs and their flip relation."""
    ptr = np.zeros(n_faces + 1, dtype=np.int64)
    for e in range(f1.shape[0]):
        ptr[f1[e] + 1] += 1
        ptr[f2[e] + 1] += 1
    for f in range(n_faces):
        ptr[f + 1] += ptr[f]
    fill = ptr[:-1].copy()
    nbr = np.empty(ptr[-1], dtype=np.int64)
    r = np.empty(ptr[-1], dtype=np.int64)
    for e in range(f1.shape[0]):
        nbr[fill[f1[e]]], r[fill[f1[e]]] = f2[e], rel[e]
        fill[f1[e]] += 1
        nbr[fill[f2[e]]], r[fill[f2[e]]] = f1[e], rel[e]
        fill[f2[e]] += 1
    return ptr, nbr, r


@numba.njit(cache=True)
def _component_stats(vertices, faces, comp, n_comp):
    """Per component: the enclosed volume measured from its centroid (origin-free for a
    closed component; for an open one, the volume closed by a fan from that point), the
    diagonal of its bounding box, and its first face."""
    centre = np.zeros((n_comp, 3))
    count = np.zeros(n_comp)
    lo = np.full((n_comp, 3), np.inf)
    hi = np.full((n_comp, 3), -np.inf)
    first = np.full(n_comp, -1, dtype=np.int64)
    for f in range(faces.shape[0]):
        c = comp[f]
        if first[c] < 0:
            first[c] = f
        count[c] += 1.0
        for k in range(3):
            for d in range(3):
                x = vertices[faces[f, k], d]
                centre[c, d] += x / 3.0
                lo[c, d] = min(lo[c, d], x)
                hi[c, d] = max(hi[c, d], x)
    for c in range(n_comp):
        for d in range(3):
            centre[c, d] /= count[c]
    volume = np.zeros(n_comp)
    for f in range(faces.shape[0]):
        c = comp[f]
        a, b, e = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, az = vertices[a, 0] - centre[c, 0], vertices[a, 1] - centre[c, 1], vertices[a, 2] - centre[c, 2]
        bx, by, bz = vertices[b, 0] - centre[c, 0], vertices[b, 1] - centre[c, 1], vertices[b, 2] - centre[c, 2]
        cx, cy, cz = vertices[e, 0] - centre[c, 0], vertices[e, 1] - centre[c, 1], vertices[e, 2] - centre[c, 2]
        volume[c] += (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)) / 6.0
    span = np.empty(n_comp)
    for c in range(n_comp):
        span[c] = math.sqrt((hi[c, 0] - lo[c, 0]) ** 2 + (hi[c, 1] - lo[c, 1]) ** 2 + (hi[c, 2] - lo[c, 2]) ** 2)
    return volume, span, first


def single_sided(faces) -> np.ndarray:
    """``faces`` with repeated and double-sided faces resolved (see the module docstring):
    a face repeated with the same winding is kept once; a face together with its reverse
    adds nothing to the winding number, so such pairs are taken out, and one copy is put
    back of each piece they form that is closed (a closed model exported double-sided).
    Faces in their original order; ``faces`` itself when that leaves none."""
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        return faces
    ordered = np.sort(faces, axis=1)
    # winding parity: whether the face is an even (cyclic) permutation of its sorted vertices
    lowest = np.argmin(faces, axis=1)
    rows = np.arange(len(faces))
    even = faces[rows, (lowest + 1) % 3] < faces[rows, (lowest + 2) % 3]
    keyed = np.column_stack([ordered, even])
    _, first = np.unique(keyed, axis=0, return_index=True)
    first = np.sort(first)  # one face per (vertices, winding), the first in the file
    _, group, counts = np.unique(ordered[first], axis=0, return_inverse=True, return_counts=True)
    paired = counts[group.ravel()] == 2  # both windings of the same three vertices
    if not paired.any():
        return faces[first]
    kept = first[~paired]
    copies = first[paired]
    copies = copies[even[copies]]  # one of each pair: the one wound like its sorted vertices
    closed = copies[_closed_pieces(faces[copies])]
    out = np.sort(np.concatenate([kept, closed]))
    return faces[out] if len(out) else faces


def _pieces(faces: np.ndarray) -> tuple | None:
    """``(count, label per face, open per piece)``: the edge-connected pieces across edges
    of exactly two faces (as :func:`orient_faces` walks them), and which hold a boundary
    edge (an edge of one face); None, at the cost of one edge count, for a mesh without a
    boundary edge (every piece closed)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(faces)
    _, _, _, _, key, order = _half_edges(faces)
    sorted_key = key[order]
    first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    size = np.diff(np.r_[first, len(order)])
    if not (size == 1).any():
        return None
    pair = first[size == 2]
    graph = coo_matrix((np.ones(len(pair)), (order[pair] // 3, order[pair + 1] // 3)), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    open_piece = np.zeros(count, dtype=bool)
    open_piece[label[order[first[size == 1]] // 3]] = True
    return count, label, open_piece


def _closed_pieces(faces: np.ndarray) -> np.ndarray:
    """Mask of the faces in edge-connected pieces (across edges of exactly two faces)
    that have no boundary edge (an edge of one face)."""
    pieces = _pieces(faces)
    if pieces is None:
        return np.ones(len(faces), dtype=bool)
    _, label, open_piece = pieces
    return ~open_piece[label]


FLAT_PIECE = 0.02
"""An open piece whose vertices all lie within this fraction of its bounding-box diagonal
of one plane is flat (:func:`flat_open_pieces`)."""


def flat_open_pieces(vertices, faces) -> np.ndarray:
    """Mask of the faces in open, flat edge-connected pieces (leaf cards, decals, a plane
    for a window or a wall): pieces with a boundary edge whose vertices lie within
    :data:`FLAT_PIECE` of their diagonal of one plane. Alone, such a piece encloses
    nothing, but with its rim capped its winding number is +-1/2 on both sides of it, and
    which side reads as inside follows the way it happens to face: a tree of 8,000 leaf
    cards around a closed trunk filled 216 voxels of crown, 235 with the cards turned
    over, 56 of them in both. (Several such pieces may still bound a room together:
    :func:`procmod.targets.files.mesh_inside` decides whether to leave them out.) All
    False, at the cost of one edge count, for a mesh without boundary edges."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = len(faces)
    if n == 0:
        return np.zeros(0, dtype=bool)
    pieces = _pieces(faces)
    if pieces is None:
        return np.zeros(n, dtype=bool)  # no boundary edge: no open piece
    count, label, open_piece = pieces
    corner_label = np.repeat(label, 3)
    points = vertices[faces.ravel()]
    # per piece: the plane of least squares through its corners, and how far they lie from it
    weight = np.bincount(corner_label, minlength=count).astype(np.float64)
    mean = np.stack([np.bincount(corner_label, points[:, k], minlength=count) for k in range(3)], axis=1)
    centred = points - (mean / weight[:, None])[corner_label]
    scatter = np.zeros((count, 3, 3))
    np.add.at(scatter, corner_label, centred[:, :, None] * centred[:, None, :])
    _, axes = np.linalg.eigh(scatter)
    off = np.abs((centred * axes[:, :, 0][corner_label]).sum(1))  # along each piece's least direction
    thickness = np.zeros(count)
    np.maximum.at(thickness, corner_label, off)
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    np.minimum.at(lo, corner_label, points)
    np.maximum.at(hi, corner_label, points)
    flat = open_piece & (thickness <= FLAT_PIECE * np.linalg.norm(hi - lo, axis=1))
    return flat[label]


def orient_faces(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Faces wound consistently and outward, per edge-connected component (see the module
    docstring). Returns ``(faces, component label per face)``."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.array(faces, dtype=np.int64).reshape(-1, 3)
    n = len(faces)
    if n == 0:
        return faces, np.zeros(0, dtype=np.int64)
    a, _, _, _, key, order = _half_edges(faces)
    sorted_key = key[order]
    first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    size = np.diff(np.r_[first, len(order)])
    pair = first[size == 2]  # edges of exactly two faces join them; boundary and non-manifold edges do not
    e1, e2 = order[pair], order[pair + 1]
    rel = (a[e1] == a[e2]).astype(np.int64)  # the same direction: one of them must turn over
    ptr, nbr, r = _adjacency(n, e1 // 3, e2 // 3, rel)
    comp, parity, n_comp = _walk(n, ptr, nbr, r)
    turn = parity == 1
    faces[turn] = faces[turn][:, ::-1]
    volume, span, _ = _component_stats(vertices, faces, comp, n_comp)
    inverted = np.flatnonzero(volume < -1e-9 * span ** 3)
    if len(inverted):
        keep = np.zeros(n_comp, dtype=bool)  # inward-facing components that are cavities
        outward = ~np.isin(comp, inverted)
        tested = inverted[np.argsort(volume[inverted])][:CAVITY_TESTS]
        if outward.any():
            # several faces of each: one probe decided before, and a piece overlapping an
            # outward one (partly inside it) was taken for a cavity and carved out of it
            w, owner = _probe_winding(vertices, faces, comp, tested, outward)
            for c in tested:
                keep[c] = bool(np.all(w[owner == c] >= 0.5))
        flipped = inverted[~keep[inverted]]
        turn = np.isin(comp, flipped)
        if len(flipped) and outward.any():
            # an outward piece wholly inside a piece that is turned over is that piece's inner
            # wall: a hollow part exported inside out (every normal flipped) has its outer
            # shell facing in and its cavity's wall facing out, and read as filled
            facing_out = np.flatnonzero(volume > 1e-9 * span ** 3)
            candidates = facing_out[np.argsort(-volume[facing_out])][:CAVITY_TESTS]
            if len(candidates):
                w, owner = _probe_winding(vertices, faces, comp, candidates, turn)
                walls = [c for c in candidates if np.all(w[owner == c] <= -0.5)]  # inside, wound inward
                turn |= np.isin(comp, walls)
        faces[turn] = faces[turn][:, ::-1]
    return faces, comp


def _probe_winding(vertices, faces, comp, pieces, around):
    """Winding numbers of the faces ``around`` (a mask) at the centroids of up to
    :data:`CAVITY_PROBES` faces of each of ``pieces`` (spread over it); with the piece of
    each probe."""
    probes, owner = [], []
    for c in pieces:
        members = np.flatnonzero(comp == c)
        picked = members[np.linspace(0, len(members) - 1, min(CAVITY_PROBES, len(members))).astype(np.int64)]
        probes.append(vertices[faces[picked]].mean(axis=1))
        owner += [c] * len(picked)
    return winding_numbers(vertices, faces[around], np.concatenate(probes)), np.asarray(owner)


__all__ = ["boundary_chain", "cap_tree", "closed_winding", "inside_voxels", "orient_faces", "single_sided",
           "winding_numbers"]
