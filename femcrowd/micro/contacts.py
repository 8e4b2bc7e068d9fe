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

__all__ = [
    "as_segments",
    "merge_collinear",
    "point_segment_distance",
    "WallSet",
    "Constraints",
    "CandidateList",
    "pair_gaps",
]


# --------------------------------------------------------------------------
# segments
# --------------------------------------------------------------------------


def as_segments(segs) -> np.ndarray:
    """Return ``segs`` as a float (S, 2, 2) array (an empty (0, 2, 2) if None)."""
    if segs is None:
        return np.zeros((0, 2, 2))
    a = np.asarray(segs, dtype=float)
    if a.size == 0:
        return np.zeros((0, 2, 2))
    if a.ndim != 3 or a.shape[1:] != (2, 2):
        raise ValueError(f"segments must have shape (S, 2, 2), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("segments contain NaN or inf")
    keep = np.linalg.norm(a[:, 1] - a[:, 0], axis=1) > 0
    return np.ascontiguousarray(a[keep])


def merge_collinear(segs, rtol: float = 1e-9) -> np.ndarray:
    """Merge chains of collinear segments that share end points.

    Mesh boundary edges come as many short collinear pieces; a disc resting on
    a straight wall would otherwise see one (duplicate) constraint per piece.
    Runs once at set-up (a loop over the segments is fine there).
    """
    segs = as_segments(segs)
    S = len(segs)
    if S < 2:
        return segs
    pts = segs.reshape(-1, 2)
    scale = max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]), 1e-300)
    key = np.round(pts / (scale * rtol * 10)).astype(np.int64)
    _, vid = np.unique(key, axis=0, return_inverse=True)
    vid = vid.reshape(S, 2)
    nv = vid.max() + 1
    deg = np.bincount(vid.ravel(), minlength=nv)
    d = segs[:, 1] - segs[:, 0]
    d /= np.linalg.norm(d, axis=1)[:, None]
    # incidence: for each vertex of degree 2 its two segments
    inc = [[] for _ in range(nv)]
    for s in range(S):
        inc[vid[s, 0]].append(s)
        inc[vid[s, 1]].append(s)
    # union-find over segments joined at collinear degree-2 vertices
    parent = np.arange(S)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for v in np.flatnonzero(deg == 2):
        s1, s2 = inc[v]
        if abs(d[s1, 0] * d[s2, 1] - d[s1, 1] * d[s2, 0]) < 1e3 * rtol:
            a, b = find(s1), find(s2)
            if a != b:
                parent[b] = a
    roots = np.array([find(s) for s in range(S)])
    out = []
    for root in np.unique(roots):
        members = np.flatnonzero(roots == root)
        if len(members) == 1:
            out.append(segs[members[0]])
            continue
        p = segs[members].reshape(-1, 2)
        t = (p - p[0]) @ d[root]
        out.append(np.array([p[np.argmin(t)], p[np.argmax(t)]]))
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
        segs = merge_collinear(segments) if merge else as_segments(segments)
        self.segments = segs
        self.a = np.ascontiguousarray(segs[:, 0])
        self.b = np.ascontiguousarray(segs[:, 1])
        self.n = len(segs)
        self._tree = None
        self.spacing = spacing
        if self.n and spacing is not None:
            self._build(spacing)

    def _build(self, h):
        L = np.linalg.norm(self.b - self.a, axis=1)
        k = np.maximum(np.ceil(L / h).astype(int), 1)  # pieces per segment
        seg = np.repeat(np.arange(self.n), k + 1)
        start = np.repeat(np.cumsum(k + 1) - (k + 1), k + 1)
        t = (np.arange(len(seg)) - start) / np.repeat(k, k + 1)
        pts = self.a[seg] + t[:, None] * (self.b - self.a)[seg]
        self._tree = cKDTree(pts)
        self._sample_seg = seg
        self.spacing = float(h)
        self._halfgap = 0.5 * float(np.max(L / k))

    def near(self, q, radius: float, tree: cKDTree | None = None):
        """(disc, segment) index pairs with ``dist(q_disc, segment) <= radius``.

        Returns arrays (i, s, p, dist) with the closest points p and distances.
        """
        empty = (np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros(0))
        if self.n == 0 or len(q) == 0:
            return empty
        h = max(radius, 1e-9)
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
        for s in range(0, len(q), chunk):
            x = q[s : s + chunk, None, :]
            ab = (self.b - self.a)[None]
            t = np.clip(((x - self.a[None]) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
            dd = x - (self.a[None] + t[..., None] * ab)
            out[s : s + chunk] = np.sqrt((dd * dd).sum(-1).min(axis=1))
        return out


# --------------------------------------------------------------------------
# constraint rows at a configuration
# --------------------------------------------------------------------------


def pair_gaps(q, r, i, j):
    """Gaps D_ij and unit vectors e_ij = (q_j - q_i)/|q_j - q_i| for pairs (i, j)."""
    dq = q[j] - q[i]
    L = np.sqrt(np.einsum("ij,ij->i", dq, dq))
    with np.errstate(invalid="ignore", divide="ignore"):
        e = dq / L[:, None]
    bad = ~(L > 0)
    if bad.any():  # coincident centres: any direction is a valid sub-gradient
        e[bad] = (1.0, 0.0)
    return L - r[i] - r[j], e


class Constraints:
    """The linearised constraints ``B v <= d`` of one step, in compact form.

    Rows ``0..mp-1`` are disc pairs (``c . (v_i - v_j)``), rows ``mp..m-1``
    are wall contacts (``c . v_i``). ``D`` are the gaps at the configuration.
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

    # B v and B^T lambda ----------------------------------------------------
    # Both go through a cached scipy CSR matrix: its compiled mat-vec is 5-10x
    # faster than gathering/scattering with numpy fancy indexing, and the
    # solvers call them hundreds of times per projection.
    def _csr(self):
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
        w = np.concatenate([x[: self.mp], x[: self.mp], x[self.mp :]])
        return np.bincount(np.concatenate([self.pi, self.pj, self.wi]), weights=w, minlength=self.N)

    def norm2_bound(self):
        """Upper bound of ||B||^2 (Gershgorin on |B||B|^T), for Uzawa's step."""
        if self.m == 0:
            return 0.0
        ap, aw = np.abs(self.cp), np.abs(self.cw)
        colsum = np.bincount(
            self._cols,
            weights=np.concatenate([ap[:, 0], ap[:, 1], ap[:, 0], ap[:, 1], aw[:, 0], aw[:, 1]]),
            minlength=2 * self.N,
        ).reshape(self.N, 2)
        rs = np.concatenate(
            [(ap * (colsum[self.pi] + colsum[self.pj])).sum(1), (aw * colsum[self.wi]).sum(1)]
        )
        return float(rs.max())

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
        p = rows[rows < self.mp]
        w = rows[rows >= self.mp] - self.mp
        return Constraints(self.N, self.pi[p], self.pj[p], self.cp[p], self.wi[w], self.ws[w],
                           self.cw[w], self.D[np.concatenate([p, self.mp + w])])


def _wall_gap(q, r, i, p):
    dx = q[i] - p
    L = np.sqrt(np.einsum("ij,ij->i", dx, dx))
    with np.errstate(invalid="ignore", divide="ignore"):
        n = dx / L[:, None]
    bad = ~(L > 0)
    if bad.any():
        n[bad] = (1.0, 0.0)
    return L - r[i], n


# --------------------------------------------------------------------------
# Verlet candidate list
# --------------------------------------------------------------------------


class CandidateList:
    """Disc-disc and disc-wall pairs whose gap is <= ``skin`` at the build.

    With s_i = |q_i - q_i(build)| + tau |u_i| (displacement since the build
    plus the move of the step), an unlisted pair has D_ij(q) + tau G_ij . u
    >= D_ij(build) - s_i - s_j > 0 (triangle inequality), so the list is exact
    (it contains every pair that can touch or whose linearised constraint can
    bind) while the two largest s_i sum to less than ``skin``
    (:meth:`travel_ok`; a wall pair needs s_i < skin).
    """

    def __init__(self, q, r, walls: WallSet | None, skin: float):
        q = np.asarray(q, float)
        r = np.asarray(r, float)
        N = len(q)
        self.skin = float(skin)
        self.q_ref = q.copy()
        self.nwalls = 0 if walls is None else walls.n
        if N == 0:
            self.pi = self.pj = self.wi = self.ws = np.zeros(0, np.intp)
            return
        tree = cKDTree(q)
        rmax = float(r.max())
        P = tree.query_pairs(2 * rmax + self.skin, output_type="ndarray")
        if len(P):
            D, _ = pair_gaps(q, r, P[:, 0], P[:, 1])
            P = P[D <= self.skin]
        self.pi = np.ascontiguousarray(P[:, 0]).astype(np.intp)
        self.pj = np.ascontiguousarray(P[:, 1]).astype(np.intp)
        if walls is not None and walls.n:
            wi, ws, _, dist = walls.near(q, rmax + self.skin, tree=tree)
            keep = dist - r[wi] <= self.skin
            self.wi, self.ws = wi[keep], ws[keep]
        else:
            self.wi = self.ws = np.zeros(0, np.intp)

    @classmethod
    def from_arrays(cls, q_ref, skin, nwalls, pi, pj, wi, ws) -> "CandidateList":
        """A list as it was built (a checkpoint's: :meth:`arrays`), with its rows in the same order."""
        cl = cls.__new__(cls)
        cl.q_ref, cl.skin, cl.nwalls = np.array(q_ref, float).reshape(-1, 2), float(skin), int(nwalls)
        cl.pi, cl.pj, cl.wi, cl.ws = (np.array(a, np.intp) for a in (pi, pj, wi, ws))
        return cl

    def arrays(self) -> dict:
        """The list as arrays, the arguments of :meth:`from_arrays`."""
        return {"q_ref": self.q_ref, "skin": self.skin, "nwalls": self.nwalls, "pi": self.pi, "pj": self.pj,
                "wi": self.wi, "ws": self.ws}

    @property
    def m(self):
        return len(self.pi) + len(self.wi)

    def keys(self, N):
        """Integer keys identifying rows (to carry multipliers across rebuilds)."""
        W = max(self.nwalls, 1)
        return np.concatenate([self.pi * N + self.pj, -1 - (self.wi * W + self.ws)])

    def travel_ok(self, q, step=None) -> bool:
        """True if the list covers a move from q by ``step`` (per-disc lengths)."""
        dq = q - self.q_ref
        p = np.sqrt(np.einsum("ij,ij->i", dq, dq))
        if step is not None:
            p += step
        if len(p) < 2:
            return len(p) == 0 or p[0] < self.skin  # only walls
        two = np.partition(p, len(p) - 2)[-2:]
        return bool(two.sum() < self.skin)

    def constraints(self, q, r, walls: WallSet | None) -> Constraints:
        """Gaps and unit vectors of all listed rows at configuration q."""
        N = len(q)
        Dp, e = pair_gaps(q, r, self.pi, self.pj)
        if len(self.wi):
            p, _ = point_segment_distance(q[self.wi], walls.a[self.ws], walls.b[self.ws])
            Dw, n = _wall_gap(q, r, self.wi, p)
        else:
            Dw, n = np.zeros(0), np.zeros((0, 2))
        return Constraints(N, self.pi, self.pj, e, self.wi, self.ws, -n, np.concatenate([Dp, Dw]))

    def remove(self, keep_mask):
        """Drop discs (keep_mask False) and renumber the rows; returns kept row mask."""
        newidx = np.cumsum(keep_mask) - 1
        kp = keep_mask[self.pi] & keep_mask[self.pj]
        kw = keep_mask[self.wi]
        self.pi, self.pj = newidx[self.pi[kp]], newidx[self.pj[kp]]
        self.wi, self.ws = newidx[self.wi[kw]], self.ws[kw]
        self.q_ref = self.q_ref[keep_mask]
        return np.concatenate([kp, kw])
