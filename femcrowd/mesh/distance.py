"""Distance to the exits: the geodesic (shortest path inside the domain) field d.

The desired velocity of evacuation scenes is U = -v grad d / |grad d|
(docs/model.md, "Desired velocity"), so d must be accurate at the nodes and
its P1 gradient must point the right way in every triangle.

Method: the Eikonal equation |grad d| = 1, d = 0 on the exits, solved on the
triangles with the Fast Iterative Method (Jeong & Whitaker 2008) and the exact
local solver of a P1 triangle (Hopf-Lax: the best point on the opposite edge
with d interpolated linearly there, or an end point). This is the same
discrete solution as fast marching / fim-python, converged to 1e-6 of an edge
length; error O(h), none where the paths are parallel lines to a straight exit.

Why hand-written (numpy, vectorised over the active list; the loop is over
wave fronts, not nodes) rather than a library: against potpourri3d, fim-python,
pygeodesic and scikit-fmm on the same meshes (``benchmarks/distance.py
--compare``; figures in docs/performance.md, "Distance field: the libraries
compared") it is the fastest at 10^6 triangles with the best errors, accepts
non-manifold meshes and adds no dependency.

Seeding: exit nodes get 0 and the nodes of the triangles around each exit node
get their straight-line distance to the exit *segments* (exact for a straight
exit), so the field is the distance to the segments, not to the exit nodes.
Nodes of a component without an exit keep ``np.inf`` (no NaN, no warning).
The mesh need not be manifold nor consistently oriented; a node where two
parts of the domain touch lets paths through (the closure of the domain).

Accuracy (tests/mesh/test_distance.py): where the exit is in straight sight the
result is exact; around a convex obstacle the error is O(h) (0.3 h max,
0.02 h mean); past the end of a door or a reflex corner d is the distance to a
point and the error is O(h log 1/h) (0.3 h to 0.6 h max), as for every fast
marching scheme. It is an overestimate there; gradient directions are within
1 degree on average, up to 12 degrees on walls that the rays graze.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .triangles import doubled_areas, surface_areas, surface_edges

#: The iteration stops changing a node when it would decrease by less than this fraction of
#: the mean edge length (1e-6: the result agrees to 3 digits with a 1e-9 tolerance, at half
#: the cost).
REL_TOL = 1e-6

#: Width of the band of active nodes relaxed per iteration, in mean edge lengths (see _fim;
#: 2, 3 and 4 were within 15 % of each other on the two 10^6-triangle halls).
BAND = 3.0


def exit_distance(points, triangles, exit_edges, cost=None) -> np.ndarray:
    """Shortest-path length inside the triangulated domain from every mesh node to the nearest exit.
    points (N, 2) float, triangles (M, 3) int, exit_edges (E, 2) int node pairs of the boundary edges that are exits;
    cost: optional (M,) cost per unit length of each triangle (> 0; default 1, the geodesic distance).
    Returns (N,) float; np.inf at nodes with no path to any exit (regions cut off from every exit).
    Several solves on one mesh: :class:`Eikonal` keeps the mesh's stencils."""
    return Eikonal(points, triangles).solve(exit_edges, cost)


class Eikonal:
    """|grad phi| = cost on a triangulated domain, phi = 0 on exit edges: the stencils of the mesh (corner
    geometry, corners grouped by node) built once, solved for any exits and cost per triangle (Hughes 2002:
    cost 1 / f(rho) gives the route choice of a crowd that sees congestion)."""

    def __init__(self, points, triangles, elevation=None):
        """elevation: the z of each node of a building (docs/floors.md), whose local solves then use the edges and
        areas of the triangles on the surface; the seeds at the exits stay in plan (exits lie on a floor)."""
        p = np.asarray(points, dtype=float)
        t = np.asarray(triangles, dtype=np.int64)
        if t.size == 0:
            t = t.reshape(0, 3)
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"points must have shape (N, 2), got {p.shape}")
        if t.ndim != 2 or t.shape[1] != 3:
            raise ValueError(f"triangles must have shape (M, 3), got {t.shape}")
        if t.size and (t.min() < 0 or t.max() >= len(p)):
            raise ValueError(f"triangles refer to nodes outside 0..{len(p) - 1}")
        if not np.isfinite(p).all():
            raise ValueError("points contain NaN or inf")
        self.points, self.triangles, self.elevation = p, t, elevation
        self._corners = None
        self._seeds = {}   # per set of exit edges

    def solve(self, exit_edges, cost=None) -> np.ndarray:
        """phi at the nodes (np.inf where no exit can be reached) for these exit edges (E, 2) and the cost per
        triangle (M,) (None: 1 everywhere, the geodesic distance)."""
        return self.solve_each([exit_edges], cost)[0]

    def solve_each(self, exit_edges, cost=None) -> np.ndarray:
        """(K, N): phi of each of K sets of exit edges (a list of (E, 2) arrays), all for the same cost per triangle:
        bit for bit the K solves of :meth:`solve`, in one iteration over K copies of the mesh (the wave fronts of
        every set advance together, so the fixed cost of an iteration, which dominates on small meshes, is paid
        once rather than K times)."""
        cost = self._checked_cost(cost)
        seeded = [self._seeded(edges, cost) for edges in exit_edges]
        d = np.concatenate(seeded) if seeded else np.empty(0)
        if len(self.triangles) == 0 or not np.isfinite(d).any():
            return d.reshape(len(seeded), len(self.points))
        if self._corners is None:
            self._corners = _Corners(self.points, self.triangles, self.elevation)
        corners = self._corners if len(seeded) == 1 else self._corners.tiled(len(seeded))
        slowness = None if cost is None else np.append(np.tile(np.repeat(cost, 3), len(seeded)), 1.0)
        return _fim(corners, np.append(d, np.inf), slowness)[:-1].reshape(len(seeded), len(self.points))

    def _checked_cost(self, cost):
        if cost is not None:
            cost = np.asarray(cost, dtype=float)
            if cost.shape != (len(self.triangles),) or not (cost > 0).all():
                raise ValueError(f"cost must be positive with one value per triangle ({len(self.triangles)})")
        return cost

    def _seeded(self, exit_edges, cost) -> np.ndarray:
        """The start of the iteration for these exit edges: 0 on the exits, the seeds around them, inf elsewhere
        (their geometry found once per set of exit edges, weighed by each cost)."""
        exits = np.asarray(exit_edges, dtype=np.int64)
        if exits.size == 0:
            exits = exits.reshape(0, 2)
        if exits.ndim != 2 or exits.shape[1] != 2:
            raise ValueError(f"exit_edges must have shape (E, 2), got {exits.shape}")
        n = len(self.points)
        if exits.size and (exits.min() < 0 or exits.max() >= n):
            raise ValueError(f"exit_edges refer to nodes outside 0..{n - 1}")
        key = exits.tobytes()
        if key not in self._seeds:
            self._seeds[key] = _Seeds(self.points, self.triangles, exits)
        return self._seeds[key].values(n, cost)


class _Seeds:
    """The exit nodes of a set of exit edges and the straight-line candidates around them (:func:`_seed_candidates`):
    what the start of the iteration needs, found once."""

    def __init__(self, p, t, exits):
        self.exit_nodes = np.unique(exits)
        self.node, self.length, self.triangle = (
            _seed_candidates(p, t, self.exit_nodes, exits[exits[:, 0] != exits[:, 1]])
            if len(exits) and len(t) else (np.empty(0, np.int64), np.empty(0), np.empty(0, np.int64)))

    def values(self, n, cost=None) -> np.ndarray:
        """(n,): 0 on the exit nodes, the least candidate length (times the cost of its triangle) at the nodes
        around them, inf elsewhere."""
        d = np.full(n, np.inf)
        d[self.exit_nodes] = 0.0
        np.minimum.at(d, self.node, self.length if cost is None else self.length * cost[self.triangle])
        return d


class _Corners:
    """Geometry of the local solver at every corner of every triangle, and the corners of each node.

    Corner 3 i + k is vertex k (= C) of triangle i; A and B are the next two vertices. The solver
    needs |AB| (as 1/|AB|), |CA|, |CB|, and C in the frame of the edge AB: its abscissa along AB
    from A (wpar) and its distance to the line AB (wperp): ``geometry`` holds these five rows, a column per
    corner.

    The corners that update a node (its own, C = node) and those that read it (A or B = node) are
    rows of two tables padded with a last, empty corner whose nodes are the last node of d (kept at inf
    by the iteration): an iteration gathers the corners of a set of nodes with one index and takes
    each node's least value along a row, with no per-corner bookkeeping in Python.
    """

    def __init__(self, p, t, elevation=None):
        n, m = len(p), len(t)
        self.nodes, self.copies, self.empty = n, 1, 3 * m
        index_type = np.int32 if max(n + 1, 3 * m + 1) < 2**31 - 1 else np.int64
        if elevation is None:
            x0, x1, x2 = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
            # edge[:, k] = length of the edge opposite vertex k
            edge = np.stack([np.hypot(*(x2 - x1).T), np.hypot(*(x0 - x2).T), np.hypot(*(x1 - x0).T)], axis=1)
            area2 = np.abs(doubled_areas(p, t))
        else:   # on the surface of a building
            edge, area2 = surface_edges(p, elevation, t), 2 * surface_areas(p, elevation, t)
        # each row written in place: copies of arrays this size are slow to touch (docs/performance.md, "Route choice")
        self.geometry = np.zeros((5, 3 * m + 1))
        ca, cb, iL, wpar, wperp = self.geometry[:, :-1]
        L = edge.ravel()  # |AB|: edge opposite C
        cb[:] = np.roll(edge, -1, axis=1).ravel()  # |CB| is opposite A
        ca[:] = np.roll(edge, -2, axis=1).ravel()  # |CA| is opposite B
        with np.errstate(divide="ignore"):
            iL[:] = np.where(L > 0, 1.0 / L, 0.0)
        wpar[:] = (ca * ca + L * L - cb * cb) * 0.5 * iL
        wperp[:] = np.repeat(area2, 3) * iL
        self.mean_edge = float(edge.mean()) if m else 0.0
        self.C = np.full(3 * m + 1, n, dtype=index_type)
        self.AB = np.full((2, 3 * m + 1), n, dtype=index_type)
        self.C[:-1] = t.ravel()
        self.AB[0, :-1], self.AB[1, :-1] = np.roll(t, -1, axis=1).ravel(), np.roll(t, -2, axis=1).ravel()
        self.own, self.read = _corner_tables(self.C[:-1], n, index_type)
        self._tiled = {}   # per number of copies: the corners of that many copies of the mesh (solve_each)

    def tiled(self, copies: int) -> "_Corners":
        """The corners of `copies` disjoint copies of the mesh (copy j: nodes j N .. (j + 1) N - 1, one empty corner
        and one last node for all), the same geometry and mean edge (so the same tolerance and band), built once per
        number of copies."""
        if copies not in self._tiled:
            n, m3 = self.nodes, len(self.C) - 1
            index_type = np.int32 if max(copies * n + 1, copies * m3 + 1) < 2**31 - 1 else np.int64

            def tile(nodes):   # the nodes of the corners of copy 0 (the last corner the empty one) -> all copies
                shifted = [nodes[..., :-1] + j * n for j in range(copies)]
                empty = np.full(nodes.shape[:-1] + (1,), copies * n)
                return np.concatenate(shifted + [empty], axis=-1).astype(index_type)

            tiled = object.__new__(_Corners)
            tiled.nodes, tiled.copies, tiled.empty = n, copies, copies * m3
            tiled.mean_edge = self.mean_edge
            tiled.C, tiled.AB = tile(self.C), tile(self.AB)
            tiled.geometry = np.column_stack([np.tile(self.geometry[:, :-1], copies), self.geometry[:, -1:]])
            tiled.own, tiled.read = (np.concatenate([np.where(table == m3, copies * m3, table + j * m3)
                                                     for j in range(copies)]).astype(index_type)
                                     for table in (self.own, self.read))
            tiled._tiled = {}
            self._tiled[copies] = tiled
        return self._tiled[copies]

    def update(self, d, corners, slowness=None):
        """Value that the corners give to their node C from d at A and B: the P1 Hopf-Lax formula, for a cost
        per unit length `slowness` per corner (None: 1). phi / s solves the unit equation in a triangle of cost
        s, and the formula is positively homogeneous: the value is s times the unit one of dA / s, dB / s."""
        # take, not fancy indexing, which is slower with an index of 2 dimensions or for rows (docs/performance.md)
        (dA, dB), geometry = d.take(self.AB.take(corners, axis=1)), self.geometry.take(corners, axis=1)
        if slowness is None:
            return self._unit(dA, dB, geometry)
        s = slowness.take(corners)
        return s * self._unit(dA / s, dB / s, geometry)

    @staticmethod
    def _unit(dA, dB, geometry):
        """The unit-cost Hopf-Lax value at the corners' nodes C from the values dA, dB at A and B (call under
        np.errstate(invalid="ignore", divide="ignore"): inf - inf at corners that the front has not reached)."""
        ca, cb, iL, wpar, wperp = geometry
        best = np.minimum(dA + ca, dB + cb)  # through an end point
        du = dB - dA
        c = du * iL  # cosine of the angle between AB and the incoming ray
        ok = np.abs(c) < 1  # False for inf - inf too
        sine = np.sqrt(np.where(ok, 1.0 - c * c, 1.0))
        s = (wpar - c * wperp / sine) * iL  # where the ray crosses AB, in [0, 1]
        ok &= (s > 0) & (s < 1)
        inner = dA + s * du + wperp / sine
        return np.where(ok, np.minimum(best, inner), best)


def _corner_tables(C, n, index_type):
    """The corners that update each of the n nodes (C = node; corner c is vertex c % 3 of triangle c // 3) and those
    that read it (the other two corners of the same triangles): tables (n, most such corners of a node) padded with
    the empty corner, len(C). The corners grouped by node through scipy's CSR -> CSC (a counting sort, in C); the
    tables filled a column at a time (as many as a node has triangles at most): a loop over columns, not nodes,
    with temporaries of one column, not of the whole tables (docs/performance.md, "Route choice")."""
    empty = len(C)
    by_node = sp.csr_matrix((np.ones(empty, dtype=bool), C, np.arange(empty + 1, dtype=index_type)),
                            shape=(empty, n)).tocsc()
    ptr, corners = by_node.indptr, by_node.indices
    count = np.diff(ptr)
    width = count.max(initial=0)
    own = np.full((n, width), empty, dtype=index_type)
    read = np.full((n, 2 * width), empty, dtype=index_type)
    for j in range(width):
        nodes = np.flatnonzero(count > j)
        c = corners.take(ptr[nodes] + j).astype(index_type)
        k = c % 3   # the corner's vertex in its triangle
        own.reshape(-1)[nodes * width + j] = c
        read.reshape(-1)[nodes * (2 * width) + j] = c - k + (k + 1) % 3
        read.reshape(-1)[nodes * (2 * width) + width + j] = c - k + (k + 2) % 3
    return own, read


def _fim(corners, d, slowness=None):
    """Fast Iterative Method. Active nodes are relaxed together (Jacobi) until they stop
    decreasing; a node that has converged wakes the neighbours that it would improve.

    Only the active nodes within BAND mean edges of the smallest active value are relaxed
    (the others wait with their tentative values): an untidy priority queue, as in the group
    marching method (Kim 2001). Relaxing every active node lets the wave run ahead through
    chains of obtuse triangles, where causality fails; the nodes it reaches first by longer
    paths are then lowered again and again by the better values that follow. Measured on the
    10^6-triangle hall of benchmarks/setup_phases.py meshed by gmsh's Delaunay without
    smoothing: each corner relaxed 24 times (15 s of CPU) without the band, 1.3 times (1-2 s)
    with it. Both orders converge to the same fixed point (equal to 3e-14 there with a zero
    tolerance); with REL_TOL they stop within 2e-7 (band) and 9e-7 (all active nodes) of it,
    for d up to 21.

    d: the start at the nodes of ``corners.copies`` disjoint copies of the mesh (:meth:`_Corners.tiled`) and inf
    at one last node (the empty corners'); each copy has its own band, so each field goes through the same
    iterations as if it were solved alone. slowness: per corner, 1 at the empty one."""
    tol = REL_TOL * corners.mean_edge
    band = BAND * corners.mean_edge
    mark = np.zeros(len(d), dtype=bool)
    active = np.empty(0, dtype=np.int64)  # the nodes to relax
    done = np.flatnonzero(np.isfinite(d))  # the seeds act as converged nodes
    with np.errstate(invalid="ignore", divide="ignore"):
        while len(done) or len(active):
            if len(done):
                readers = corners.read.take(done, axis=0).ravel()
                readers = readers[readers != corners.empty]
                target, value = corners.C.take(readers), corners.update(d, readers, slowness)
                better = value < d.take(target) - tol
                target, value = target[better], value[better]
                np.minimum.at(d, target, value)
                mark[target] = True
                mark[active] = False
                new = np.flatnonzero(mark)
                mark[new] = False
                active = np.concatenate([active, new])
            if not len(active):
                break
            d_active = d.take(active)
            if corners.copies == 1:
                lowest = d_active.min()
            else:   # the smallest active value of each copy
                copy = active // corners.nodes
                lowest = np.full(corners.copies, np.inf)
                np.minimum.at(lowest, copy, d_active)
                lowest = lowest[copy]
            near = d_active <= lowest + band
            relaxed, waiting, before = active[near], active[~near], d_active[near]
            after = np.minimum(before, corners.update(d, corners.own.take(relaxed, axis=0), slowness).min(axis=1))
            d[relaxed] = after
            converged = after >= before - tol
            done = relaxed[converged]
            active = np.concatenate([relaxed[~converged], waiting])
    return d


def _seed_values(p, t, d, exit_nodes, exits, cost=None):
    """d lowered to the straight-line distance to the exit segments at the nodes of the triangles around each exit
    node (d is 0 at the exit nodes already; :func:`_seed_candidates`). Returns the updated d (upper bounds; the
    iteration may lower them)."""
    node, length, triangle = _seed_candidates(p, t, exit_nodes, exits)
    np.minimum.at(d, node, length if cost is None else length * cost[triangle])
    return d


def _seed_candidates(p, t, exit_nodes, exits):
    """The straight paths to the exit segments from the nodes of the triangles around each exit node: (node,
    length, triangle it lies in) arrays; a node's seed is its least candidate, each weighed by its triangle's cost.

    A node w of a triangle at exit node s gets |w - s| (that segment lies in the triangle) and,
    for every exit edge (a, b) at s, its distance to that segment if w lies on a side of the line
    (a, b) where a triangle holding the edge lies, or on the line: near s, the region outside the
    domain is then a cone on the other side of that line, so the straight path is inside.
    """
    n = len(p)
    is_exit = np.zeros(n, dtype=bool)
    is_exit[exit_nodes] = True
    rows_around = np.flatnonzero(is_exit[t].any(axis=1))
    around = t[rows_around]
    candidates = []   # (node, length, row of around)
    for k in range(3):  # point candidates
        at_exit = np.flatnonzero(is_exit[around[:, k]])
        s = around[at_exit, k]
        for j in (1, 2):
            w = around[at_exit, (k + j) % 3]
            candidates.append((w, np.hypot(*(p[w] - p[s]).T), at_exit))
    if len(exits) and len(around):
        a, b = exits[:, 0], exits[:, 1]
        side_pos, side_neg = _edge_sides(p, around, exits)
        table = _edges_at_nodes(n, exits)
        for k in range(3):  # segment candidates
            rows_k = np.flatnonzero(is_exit[around[:, k]])
            for j in range(table.shape[1]):
                e = table[around[rows_k, k], j]
                rows, e = rows_k[e >= 0], e[e >= 0]
                A, B = p[a[e]], p[b[e]]
                for i in range(3):
                    w = around[rows, i]
                    side = _cross(B - A, p[w] - A)
                    good = (side == 0) | ((side > 0) & side_pos[e]) | ((side < 0) & side_neg[e])
                    candidates.append((w[good], _seg_dist(p[w[good]], A[good], B[good]), rows[good]))
    node, length, row = (np.concatenate(c) for c in zip(*candidates))
    return node, length, rows_around[row]


def _edge_sides(p, around, exits):
    """The sides of the line of each exit edge (a, b) on which a triangle of `around` holding that edge lies: masks
    (positive cross product, negative) over the edges."""
    n = len(p)
    a, b = exits[:, 0], exits[:, 1]
    edge_key = np.minimum(a, b) * n + np.maximum(a, b)
    edge_order = np.argsort(edge_key)
    sorted_keys = edge_key[edge_order]
    side_pos = np.zeros(len(exits), dtype=bool)
    side_neg = np.zeros(len(exits), dtype=bool)
    for k in range(3):
        u, v = around[:, k], around[:, (k + 1) % 3]
        key = np.minimum(u, v) * n + np.maximum(u, v)
        pos = np.minimum(np.searchsorted(sorted_keys, key), len(sorted_keys) - 1)
        hit = sorted_keys[pos] == key
        e = edge_order[pos[hit]]
        side = _cross(p[b[e]] - p[a[e]], p[around[hit, (k + 2) % 3]] - p[a[e]])
        side_pos[e[side > 0]] = True
        side_neg[e[side < 0]] = True
    return side_pos, side_neg


def _edges_at_nodes(n, exits):
    """The exit edges at each of the n nodes, as a padded table (n, largest degree), -1 for none."""
    inc_node = np.r_[exits[:, 0], exits[:, 1]]
    inc_edge = np.r_[np.arange(len(exits)), np.arange(len(exits))]
    order = np.argsort(inc_node, kind="stable")
    inc_node, inc_edge = inc_node[order], inc_edge[order]
    firsts = np.flatnonzero(np.r_[True, inc_node[1:] != inc_node[:-1]])
    slot = np.arange(len(inc_node)) - np.repeat(firsts, np.diff(np.r_[firsts, len(inc_node)]))
    table = np.full((n, slot.max() + 1), -1, dtype=np.int64)
    table[inc_node, slot] = inc_edge
    return table


def _cross(u, v):
    return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]


def _seg_dist(w, a, b):
    ab = b - a
    l2 = np.einsum("ij,ij->i", ab, ab)
    s = np.einsum("ij,ij->i", w - a, ab) / np.where(l2 > 0, l2, 1.0)
    s = np.clip(s, 0.0, 1.0)
    return np.hypot(*(w - a - s[:, None] * ab).T)
