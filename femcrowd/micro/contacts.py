"""Contact candidates, gaps and constraint gradients (Maury 2014, sec. 2.2-2.3).

For discs i < j the gap is ``D_ij = |q_j - q_i| - r_i - r_j`` with gradient
``G_ij = (.., -e_ij, .., e_ij, ..)``, ``e_ij = (q_j - q_i)/|q_j - q_i|``.
For a disc and a wall segment the gap is ``dist(q_i, segment) - r_i`` with
gradient ``n`` = unit vector from the closest point of the segment to q_i.
Both gaps are convex in q, so the linearised set of eq. (14) is an inner
approximation of the feasible set and no overlap can appear at the next step
when the constraints of every pair that *could* touch are included.

The rows of the constraint matrix ``B = -G`` are stored compactly: a row is
``c . (v_i - v_j)`` for a disc pair (``c = e_ij``) and ``c . v_i`` for a
wall contact (``c = -n``); the projection then reads ``B v <= D / tau``
(Maury 2014, eq. 16).

Candidate rows come from KD-trees (scipy.spatial.cKDTree) and are kept as a
Verlet list: every pair whose gap is at most ``skin`` when the list is built.
A pair outside the list cannot touch (nor violate its linearised constraint)
as long as the displacements of its two discs since the build, plus their
moves in the step, sum to less than ``skin``; :class:`CandidateList` checks
this after every projection and the step is redone on a rebuilt list if not.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the finest spacing (m) of the points sampled along the walls (WallSet.near samples them every radius)
WALL_SPACING = 1e-9


def as_segments(segments) -> np.ndarray:
    """Return ``segments`` as a float (S, 2, 2) array (an empty (0, 2, 2) if None)."""
    if segments is None:
        return np.zeros((0, 2, 2))
    array = np.asarray(segments, dtype=float)
    if array.size == 0:
        return np.zeros((0, 2, 2))
    if array.ndim != 3 or array.shape[1:] != (2, 2):
        raise ValueError(f"segments must have shape (S, 2, 2), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError("segments contain NaN or inf")
    keep = np.linalg.norm(array[:, 1] - array[:, 0], axis=1) > 0
    return np.ascontiguousarray(array[keep])


def merge_collinear(segments, rtol: float = 1e-9) -> np.ndarray:
    """Merge chains of collinear segments that share end points.

    Mesh boundary edges come as many short collinear pieces; a disc resting on
    a straight wall would otherwise see one (duplicate) constraint per piece.
    Runs once at set-up (a loop over the segments is fine there).
    """
    segments = as_segments(segments)
    count = len(segments)
    if count < 2:
        return segments
    points = segments.reshape(-1, 2)
    scale = max(np.ptp(points[:, 0]), np.ptp(points[:, 1]), 1e-300)
    key = np.round(points / (scale * rtol * 10)).astype(np.int64)
    _, vertex = np.unique(key, axis=0, return_inverse=True)
    vertex = vertex.reshape(count, 2)
    nvertices = vertex.max() + 1
    degree = np.bincount(vertex.ravel(), minlength=nvertices)
    direction = segments[:, 1] - segments[:, 0]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    # incidence: for each vertex of degree 2 its two segments
    incident = [[] for _ in range(nvertices)]
    for s in range(count):
        incident[vertex[s, 0]].append(s)
        incident[vertex[s, 1]].append(s)
    # union-find over segments joined at collinear degree-2 vertices
    parent = np.arange(count)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for v in np.flatnonzero(degree == 2):
        s1, s2 = incident[v]
        if abs(direction[s1, 0] * direction[s2, 1] - direction[s1, 1] * direction[s2, 0]) < 1e3 * rtol:
            first_root, second_root = find(s1), find(s2)
            if first_root != second_root:
                parent[second_root] = first_root
    roots = np.array([find(s) for s in range(count)])
    out = []
    for root in np.unique(roots):
        members = np.flatnonzero(roots == root)
        if len(members) == 1:
            out.append(segments[members[0]])
            continue
        ends = segments[members].reshape(-1, 2)
        along = (ends - ends[0]) @ direction[root]
        out.append(np.array([ends[np.argmin(along)], ends[np.argmax(along)]]))
    return np.ascontiguousarray(np.array(out, dtype=float).reshape(-1, 2, 2))


def point_segment_distance(x, a, b):
    """Closest points and distances from points x (n, 2) to segments [a, b] (n, 2)."""
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    t = np.einsum("ij,ij->i", x - a, ab) / L2
    np.clip(t, 0.0, 1.0, out=t)
    p = a + t[:, None] * ab
    dx = x - p
    return p, np.sqrt(np.einsum("ij,ij->i", dx, dx))


class WallSet:
    """Static wall segments with a KD-tree on points sampled along them.

    Any point within distance ``R`` of a segment lies within ``R + h/2`` of one
    of its sample points (spacing <= h), so a ball query with that radius finds
    every (disc, segment) pair that can be in contact.
    """

    def __init__(self, segments, merge: bool = True, spacing: float | None = None):
        segments = merge_collinear(segments) if merge else as_segments(segments)
        self.segments = segments
        self.a = np.ascontiguousarray(segments[:, 0])
        self.b = np.ascontiguousarray(segments[:, 1])
        self.n = len(segments)
        self._tree = None
        self.spacing = spacing
        if self.n and spacing is not None:
            self._build(spacing)

    def _build(self, h):
        length = np.linalg.norm(self.b - self.a, axis=1)
        pieces = np.maximum(np.ceil(length / h).astype(int), 1)  # per segment
        segment = np.repeat(np.arange(self.n), pieces + 1)
        start = np.repeat(np.cumsum(pieces + 1) - (pieces + 1), pieces + 1)
        t = (np.arange(len(segment)) - start) / np.repeat(pieces, pieces + 1)
        points = self.a[segment] + t[:, None] * (self.b - self.a)[segment]
        self._tree = cKDTree(points)
        self._sample_seg = segment
        self.spacing = float(h)
        self._halfgap = 0.5 * float(np.max(length / pieces))

    def near(self, q, radius: float, tree: cKDTree | None = None):
        """(disc, segment) index pairs with ``dist(q_disc, segment) <= radius``.

        Returns arrays (i, s, p, dist) with the closest points p and distances.
        """
        empty = (np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros(0))
        if self.n == 0 or len(q) == 0:
            return empty
        h = max(radius, WALL_SPACING)
        if self._tree is None or not (0.25 * h <= self.spacing <= 4 * h):
            self._build(h)
        if tree is None:
            tree = cKDTree(q)
        hits = tree.sparse_distance_matrix(
            self._tree, radius + self._halfgap, output_type="ndarray"
        )
        if len(hits) == 0:
            return empty
        key = hits["i"].astype(np.int64) * self.n + self._sample_seg[hits["j"]]
        key = np.unique(key)
        i = key // self.n
        s = key - i * self.n
        p, dist = point_segment_distance(q[i], self.a[s], self.b[s])
        keep = dist <= radius
        return i[keep], s[keep], p[keep], dist[keep]

    def distance(self, q):
        """Distance from each point of q (n, 2) to the nearest segment (inf if none)."""
        q = np.atleast_2d(np.asarray(q, float))
        out = np.full(len(q), np.inf)
        if self.n == 0 or len(q) == 0:
            return out
        # chunked brute force over segments for set-up use (sampling, checks)
        chunk = max(1, 2_000_000 // max(self.n, 1))
        for start in range(0, len(q), chunk):
            x = q[start : start + chunk, None, :]
            ab = (self.b - self.a)[None]
            t = np.clip(((x - self.a[None]) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
            offset = x - (self.a[None] + t[..., None] * ab)
            out[start : start + chunk] = np.sqrt((offset * offset).sum(-1).min(axis=1))
        return out


def pair_gaps(q, r, i, j, shift=None):
    """Gaps D_ij and unit vectors e_ij = (q_j - q_i)/|q_j - q_i| for pairs (i, j); shift: (pairs, 2) added to
    q_j - q_i (the pairs across a fold of a building, micro/surface.py)."""
    dq = q[j] - q[i]
    if shift is not None:
        dq += shift
    length = np.sqrt(np.einsum("ij,ij->i", dq, dq))
    with np.errstate(invalid="ignore", divide="ignore"):
        e = dq / length[:, None]
    bad = ~(length > 0)
    if bad.any():  # coincident centres: any direction is a valid sub-gradient
        e[bad] = (1.0, 0.0)
    return length - r[i] - r[j], e


class Constraints:
    """The linearised constraints ``B v <= d`` of one step, in compact form.

    Rows ``0..mp-1`` are disc pairs (``c . (v_i - v_j)``), rows ``mp..m-1``
    are wall contacts (``c . v_i``). ``D`` are the gaps at the configuration.
    ``pi``, ``pj``: the discs i < j of each pair row, ``cp``: their c (= e_ij);
    ``wi``, ``ws``: the disc and wall segment of each wall row, ``cw``: their c (= -n).
    """

    def __init__(self, N, pi, pj, cp, wi, ws, cw, D):
        self.N = int(N)
        self.pi = np.asarray(pi, np.intp)
        self.pj = np.asarray(pj, np.intp)
        self.cp = np.asarray(cp, float).reshape(-1, 2)
        self.wi = np.asarray(wi, np.intp)
        self.ws = np.asarray(ws, np.intp)
        self.cw = np.asarray(cw, float).reshape(-1, 2)
        self.D = np.asarray(D, float)
        self.mp = len(self.pi)
        self.mw = len(self.wi)
        self.m = self.mp + self.mw
        self._cols = np.concatenate(
            [2 * self.pi, 2 * self.pi + 1, 2 * self.pj, 2 * self.pj + 1, 2 * self.wi, 2 * self.wi + 1]
        )
        self._B = self._BT = None

    def _csr(self):
        """B and B^T as cached scipy CSR matrices: B v and B^T lambda go through them (their compiled mat-vec
        is 5-10x faster than gathering/scattering with numpy fancy indexing, and the solvers call them
        hundreds of times per projection)."""
        if self._B is None:
            self._B = self.to_csr()
            self._BT = self._B.T.tocsr()
        return self._B, self._BT

    def matvec(self, v):
        """B v for velocities v (N, 2) -> (m,)."""
        return self._csr()[0] @ np.asarray(v, float).reshape(-1)

    def rmatvec(self, lam):
        """B^T lambda -> (N, 2)."""
        return (self._csr()[1] @ np.asarray(lam, float)).reshape(self.N, 2)

    def per_disc_sum(self, x):
        """Sum of a per-row quantity over the rows touching each disc (pressure)."""
        weights = np.concatenate([x[: self.mp], x[: self.mp], x[self.mp :]])
        return np.bincount(np.concatenate([self.pi, self.pj, self.wi]), weights=weights, minlength=self.N)

    def norm2_bound(self):
        """Upper bound of ||B||^2 (Gershgorin on |B||B|^T), for Uzawa's step."""
        if self.m == 0:
            return 0.0
        abs_pair, abs_wall = np.abs(self.cp), np.abs(self.cw)
        colsum = np.bincount(
            self._cols,
            weights=np.concatenate([abs_pair[:, 0], abs_pair[:, 1], abs_pair[:, 0], abs_pair[:, 1],
                                    abs_wall[:, 0], abs_wall[:, 1]]),
            minlength=2 * self.N,
        ).reshape(self.N, 2)
        row_sums = np.concatenate(
            [(abs_pair * (colsum[self.pi] + colsum[self.pj])).sum(1), (abs_wall * colsum[self.wi]).sum(1)]
        )
        return float(row_sums.max())

    def to_csr(self):
        """B as a scipy CSR matrix (m, 2N), for external solvers and checks."""
        import scipy.sparse as sp

        rows = np.concatenate(
            [np.repeat(np.arange(self.mp), 4), np.repeat(self.mp + np.arange(self.mw), 2)]
        )
        cols = np.concatenate(
            [np.c_[2 * self.pi, 2 * self.pi + 1, 2 * self.pj, 2 * self.pj + 1].ravel(),
             np.c_[2 * self.wi, 2 * self.wi + 1].ravel()]
        )
        vals = np.concatenate([np.c_[self.cp, -self.cp].ravel(), self.cw.ravel()])
        return sp.csr_matrix((vals, (rows, cols)), shape=(self.m, 2 * self.N))

    def subset(self, rows):
        """The constraints restricted to the given rows (boolean mask or indices)."""
        rows = np.asarray(rows)
        if rows.dtype == bool:
            rows = np.flatnonzero(rows)
        pair_rows = rows[rows < self.mp]
        wall_rows = rows[rows >= self.mp] - self.mp
        return Constraints(self.N, self.pi[pair_rows], self.pj[pair_rows], self.cp[pair_rows], self.wi[wall_rows],
                           self.ws[wall_rows], self.cw[wall_rows],
                           self.D[np.concatenate([pair_rows, self.mp + wall_rows])])


def _wall_gap(q, r, i, closest):
    """Gaps dist(q_i, segment) - r_i of the discs i whose closest points on their segments are `closest`, and the
    unit vectors n from those points to q_i."""
    offset = q[i] - closest
    length = np.sqrt(np.einsum("ij,ij->i", offset, offset))
    with np.errstate(invalid="ignore", divide="ignore"):
        n = offset / length[:, None]
    bad = ~(length > 0)
    if bad.any():
        n[bad] = (1.0, 0.0)
    return length - r[i], n


class CandidateList:
    """Disc-disc and disc-wall pairs whose gap is <= ``skin`` at the build.

    With s_i = |q_i - q_i(build)| + tau |u_i| (displacement since the build
    plus the move of the step), an unlisted pair has D_ij(q) + tau G_ij . u
    >= D_ij(build) - s_i - s_j > 0 (triangle inequality), so the list is exact
    (it contains every pair that can touch or whose linearised constraint can
    bind) while the two largest s_i sum to less than ``skin``
    (:meth:`travel_ok`; a wall pair needs s_i < skin). The rows are those of
    :class:`Constraints`: pairs (``pi``, ``pj``), then disc-wall rows (``wi``, ``ws``).

    surface: the :class:`~femcrowd.micro.surface.Atlas` of a building (q its layout): the pairs across its folds
    are added, each with its ``shift``; None (a plane): ``shift`` is None.
    """

    def __init__(self, q, r, walls: WallSet | None, skin: float, surface=None):
        q = np.asarray(q, float)
        r = np.asarray(r, float)
        N = len(q)
        self.skin = float(skin)
        self.q_ref = q.copy()
        self.nwalls = 0 if walls is None else walls.n
        self.shift = None if surface is None else np.zeros((0, 2))
        if N == 0:
            self.pi = self.pj = self.wi = self.ws = np.zeros(0, np.intp)
            return
        tree = cKDTree(q)
        rmax = float(r.max())
        pairs = tree.query_pairs(2 * rmax + self.skin, output_type="ndarray")
        if len(pairs):
            D, _ = pair_gaps(q, r, pairs[:, 0], pairs[:, 1])
            pairs = pairs[D <= self.skin]
        self.pi = np.ascontiguousarray(pairs[:, 0]).astype(np.intp)
        self.pj = np.ascontiguousarray(pairs[:, 1]).astype(np.intp)
        if surface is not None:
            i, j, shift = surface.cross_pairs(q, 2 * rmax + self.skin)
            near = pair_gaps(q, r, i, j, shift)[0] <= self.skin
            self.pi, self.pj = np.concatenate([self.pi, i[near]]), np.concatenate([self.pj, j[near]])
            self.shift = np.concatenate([np.zeros((len(pairs), 2)), shift[near]])
        if walls is not None and walls.n:
            wall_disc, wall_segment, _, dist = walls.near(q, rmax + self.skin, tree=tree)
            keep = dist - r[wall_disc] <= self.skin
            self.wi, self.ws = wall_disc[keep], wall_segment[keep]
        else:
            self.wi = self.ws = np.zeros(0, np.intp)

    @classmethod
    def from_arrays(cls, q_ref, skin, nwalls, pi, pj, wi, ws, shift=None) -> "CandidateList":
        """A list as it was built (a checkpoint's: :meth:`arrays`), with its rows in the same order."""
        built = cls.__new__(cls)
        built.q_ref = np.array(q_ref, float).reshape(-1, 2)
        built.skin, built.nwalls = float(skin), int(nwalls)
        built.pi, built.pj, built.wi, built.ws = (np.array(rows, np.intp) for rows in (pi, pj, wi, ws))
        built.shift = None if shift is None else np.array(shift, float).reshape(-1, 2)
        return built

    def arrays(self) -> dict:
        """The list as arrays, the arguments of :meth:`from_arrays`."""
        return {"q_ref": self.q_ref, "skin": self.skin, "nwalls": self.nwalls, "pi": self.pi, "pj": self.pj,
                "wi": self.wi, "ws": self.ws, **({} if self.shift is None else {"shift": self.shift})}

    @property
    def m(self):
        return len(self.pi) + len(self.wi)

    def keys(self, N):
        """Integer keys identifying rows (to carry multipliers across rebuilds)."""
        stride = max(self.nwalls, 1)
        return np.concatenate([self.pi * N + self.pj, -1 - (self.wi * stride + self.ws)])

    def travel_ok(self, q, step=None) -> bool:
        """True if the list covers a move from q by ``step`` (per-disc lengths)."""
        dq = q - self.q_ref
        travel = np.sqrt(np.einsum("ij,ij->i", dq, dq))
        if step is not None:
            travel += step
        if len(travel) < 2:
            return len(travel) == 0 or travel[0] < self.skin  # only walls
        largest = np.partition(travel, len(travel) - 2)[-2:]
        return bool(largest.sum() < self.skin)

    def constraints(self, q, r, walls: WallSet | None) -> Constraints:
        """Gaps and unit vectors of all listed rows at configuration q."""
        N = len(q)
        D_pairs, e = pair_gaps(q, r, self.pi, self.pj, self.shift)
        if len(self.wi):
            closest, _ = point_segment_distance(q[self.wi], walls.a[self.ws], walls.b[self.ws])
            D_walls, n = _wall_gap(q, r, self.wi, closest)
        else:
            D_walls, n = np.zeros(0), np.zeros((0, 2))
        return Constraints(N, self.pi, self.pj, e, self.wi, self.ws, -n, np.concatenate([D_pairs, D_walls]))

    def remove(self, keep_mask):
        """Drop discs (keep_mask False) and renumber the rows; returns kept row mask."""
        new_index = np.cumsum(keep_mask) - 1
        keep_pairs = keep_mask[self.pi] & keep_mask[self.pj]
        keep_walls = keep_mask[self.wi]
        self.pi, self.pj = new_index[self.pi[keep_pairs]], new_index[self.pj[keep_pairs]]
        if self.shift is not None:
            self.shift = self.shift[keep_pairs]
        self.wi, self.ws = new_index[self.wi[keep_walls]], self.ws[keep_walls]
        self.q_ref = self.q_ref[keep_mask]
        return np.concatenate([keep_pairs, keep_walls])
