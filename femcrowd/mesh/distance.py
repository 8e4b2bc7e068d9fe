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

from .triangles import doubled_areas

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

    def __init__(self, points, triangles):
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
        self.points, self.triangles = p, t
        self._corners = None

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
            self._corners = _Corners(self.points, self.triangles)
        corners = self._corners if len(seeded) == 1 else self._corners.tiled(len(seeded))
        slowness = None if cost is None else np.tile(np.repeat(cost, 3), len(seeded))
        return _fim(corners, d, slowness, len(seeded)).reshape(len(seeded), len(self.points))

    def _checked_cost(self, cost):
        if cost is not None:
            cost = np.asarray(cost, dtype=float)
            if cost.shape != (len(self.triangles),) or not (cost > 0).all():
                raise ValueError(f"cost must be positive with one value per triangle ({len(self.triangles)})")
        return cost

    def _seeded(self, exit_edges, cost) -> np.ndarray:
        """The start of the iteration for these exit edges: 0 on the exits, the seeds around them, inf elsewhere."""
        p, t = self.points, self.triangles
        exits = np.asarray(exit_edges, dtype=np.int64)
        if exits.size == 0:
            exits = exits.reshape(0, 2)
        if exits.ndim != 2 or exits.shape[1] != 2:
            raise ValueError(f"exit_edges must have shape (E, 2), got {exits.shape}")
        n = len(p)
        if exits.size and (exits.min() < 0 or exits.max() >= n):
            raise ValueError(f"exit_edges refer to nodes outside 0..{n - 1}")
        d = np.full(n, np.inf)
        if len(exits) == 0:
            return d
        exit_nodes = np.unique(exits)
        d[exit_nodes] = 0.0
        if len(t) == 0:
            return d
        return _seed_values(p, t, d, exit_nodes, exits[exits[:, 0] != exits[:, 1]], cost)


class _Corners:
    """Geometry of the local solver at every corner of every triangle.

    Corner 3 i + k is vertex k (= C) of triangle i; A and B are the next two vertices. The solver
    needs |AB| (as 1/|AB|), |CA|, |CB|, and C in the frame of the edge AB: its abscissa along AB
    from A (wpar) and its distance to the line AB (wperp).
    """

    def __init__(self, p, t):
        n, m = len(p), len(t)
        index_type = np.int32 if max(n, 3 * m) < 2**31 - 1 else np.int64
        self.C = t.ravel().astype(index_type)
        self.A = np.roll(t, -1, axis=1).ravel().astype(index_type)
        self.B = np.roll(t, -2, axis=1).ravel().astype(index_type)
        x0, x1, x2 = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
        # edge[:, k] = length of the edge opposite vertex k
        edge = np.stack([np.hypot(*(x2 - x1).T), np.hypot(*(x0 - x2).T), np.hypot(*(x1 - x0).T)], axis=1)
        area2 = np.abs(doubled_areas(p, t))
        L = edge.ravel()  # |AB|: edge opposite C
        cb = np.roll(edge, -1, axis=1).ravel()  # |CB| is opposite A
        ca = np.roll(edge, -2, axis=1).ravel()  # |CA| is opposite B
        with np.errstate(divide="ignore", invalid="ignore"):
            self.iL = np.where(L > 0, 1.0 / L, 0.0)
        self.wpar = (ca * ca + L * L - cb * cb) * 0.5 * self.iL
        self.wperp = np.repeat(area2, 3) * self.iL
        self.ca, self.cb = ca, cb
        self.mean_edge = float(edge.mean()) if m else 0.0
        corners = np.arange(3 * m, dtype=index_type)
        # Corners grouped by their node C (a counting sort, in C, through scipy's COO -> CSR).
        grouped = sp.coo_matrix((corners, (self.C, corners)), shape=(n, 3 * m)).tocsr()
        self.ptr, self.own = grouped.indptr.astype(np.int64), grouped.indices.astype(index_type)
        self._tiled = {}   # per number of copies: the corners of that many copies of the mesh (solve_each)

    def tiled(self, copies: int) -> "_Corners":
        """The corners of `copies` disjoint copies of the mesh (copy j: nodes j N .. (j + 1) N - 1), the same
        geometry and mean edge (so the same tolerance and band), built once per number of copies."""
        if copies not in self._tiled:
            n, m3 = len(self.ptr) - 1, len(self.C)
            index_type = np.int32 if max(copies * n, copies * m3) < 2**31 - 1 else np.int64
            node_shift = (np.arange(copies) * n).astype(index_type)[:, None]
            corner_shift = (np.arange(copies) * m3).astype(index_type)[:, None]
            tiled = object.__new__(_Corners)
            tiled.C, tiled.A, tiled.B = ((x.astype(index_type)[None] + node_shift).ravel()
                                         for x in (self.C, self.A, self.B))
            for name in ("iL", "wpar", "wperp", "ca", "cb"):
                setattr(tiled, name, np.tile(getattr(self, name), copies))
            tiled.mean_edge = self.mean_edge
            tiled.ptr = np.concatenate([self.ptr[:-1] + j * m3 for j in range(copies)] + [[copies * m3]])
            tiled.own = (self.own.astype(index_type)[None] + corner_shift).ravel()
            tiled._tiled = {}
            self._tiled[copies] = tiled
        return self._tiled[copies]

    def owned(self, nodes):
        """Corners whose node C is in nodes (the ones that update these nodes)."""
        return _ranges(self.ptr, self.own, nodes)

    def readers(self, nodes):
        """Corners that read one of nodes as A or B: the other two corners of each triangle."""
        c = self.owned(nodes)
        base = c - c % 3
        return np.concatenate([base + (c + 1) % 3, base + (c + 2) % 3])

    def update(self, d, corners, slowness=None):
        """Value that the corners give to their node C from d at A and B: the P1 Hopf-Lax formula, for a cost
        per unit length `slowness` per corner (None: 1). phi / s solves the unit equation in a triangle of cost
        s, and the formula is positively homogeneous: the value is s times the unit one of dA / s, dB / s."""
        dA, dB = d[self.A[corners]], d[self.B[corners]]
        if slowness is None:
            return self.C[corners], self._unit(dA, dB, corners)
        s = slowness[corners]
        return self.C[corners], s * self._unit(dA / s, dB / s, corners)

    def _unit(self, dA, dB, corners):
        """The unit-cost Hopf-Lax value at the corners' nodes C from the values dA, dB at A and B."""
        best = np.minimum(dA + self.ca[corners], dB + self.cb[corners])  # through an end point
        with np.errstate(invalid="ignore", divide="ignore"):
            iL = self.iL[corners]
            du = dB - dA
            c = du * iL  # cosine of the angle between AB and the incoming ray
            ok = np.abs(c) < 1  # False for inf - inf too
            sine = np.sqrt(np.where(ok, 1.0 - c * c, 1.0))
            wperp = self.wperp[corners]
            s = (self.wpar[corners] - c * wperp / sine) * iL  # where the ray crosses AB, in [0, 1]
            ok &= (s > 0) & (s < 1)
            inner = dA + s * du + wperp / sine
        return np.where(ok, np.minimum(best, inner), best)


def _ranges(ptr, indices, nodes):
    counts = ptr[nodes + 1] - ptr[nodes]
    start = np.repeat(ptr[nodes] - np.cumsum(counts) + counts, counts)
    return indices[start + np.arange(len(start))]


def _fim(corners, d, slowness=None, copies=1):
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

    ``copies``: d holds that many fields on disjoint copies of the mesh (:meth:`_Corners.tiled`); each copy has
    its own band, so each field goes through the same iterations as if it were solved alone."""
    n = len(d)
    tol = REL_TOL * corners.mean_edge
    band = BAND * corners.mean_edge
    mark = np.zeros(n, dtype=bool)
    active = np.empty(0, dtype=np.int64)  # the nodes to relax
    done = np.flatnonzero(np.isfinite(d))  # the seeds act as converged nodes
    while len(done) or len(active):
        if len(done):
            target, value = corners.update(d, corners.readers(done), slowness)
            better = value < d[target] - tol
            target, value = target[better], value[better]
            np.minimum.at(d, target, value)
            mark[target] = True
            mark[active] = False
            new = np.flatnonzero(mark)
            mark[new] = False
            active = np.concatenate([active, new])
        if not len(active):
            break
        d_active = d[active]
        if copies == 1:
            lowest = d_active.min()
        else:   # the smallest active value of each copy
            copy = active // (n // copies)
            lowest = np.full(copies, np.inf)
            np.minimum.at(lowest, copy, d_active)
            lowest = lowest[copy]
        near = d_active <= lowest + band
        relaxed, waiting, before = active[near], active[~near], d_active[near]
        target, value = corners.update(d, corners.owned(relaxed), slowness)
        np.minimum.at(d, target, value)
        converged = d[relaxed] >= before - tol
        done = relaxed[converged]
        active = np.concatenate([relaxed[~converged], waiting])
    return d


def _seed_values(p, t, d, exit_nodes, exits, cost=None):
    """Straight-line distance to the exit segments at the nodes of the triangles around each exit
    node (d is 0 at the exit nodes already). Returns the updated d (upper bounds; the iteration
    may lower them).

    A node w of a triangle at exit node s gets |w - s| (that segment lies in the triangle) and,
    for every exit edge (a, b) at s, its distance to that segment if w lies on a side of the line
    (a, b) where a triangle holding the edge lies, or on the line: near s, the region outside the
    domain is then a cone on the other side of that line, so the straight path is inside. With a cost
    per triangle, each length is weighed by the cost of the triangle it was found in.
    """
    n = len(p)
    is_exit = np.zeros(n, dtype=bool)
    is_exit[exit_nodes] = True
    rows_around = np.flatnonzero(is_exit[t].any(axis=1))
    around = t[rows_around]
    if len(around) == 0:
        return d

    def weighed(length, rows):
        return length if cost is None else length * cost[rows_around[rows]]

    for k in range(3):  # point candidates
        at_exit = np.flatnonzero(is_exit[around[:, k]])
        s = around[at_exit, k]
        for j in (1, 2):
            w = around[at_exit, (k + j) % 3]
            np.minimum.at(d, w, weighed(np.hypot(*(p[w] - p[s]).T), at_exit))
    if len(exits) == 0:
        return d

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
                np.minimum.at(d, w[good], weighed(_seg_dist(p[w[good]], A[good], B[good]), rows[good]))
    return d


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
