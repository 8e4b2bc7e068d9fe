"""The discs on a building's surface (docs/floors.md, "Discs on stairs"): each floor and stair a plane piece with
its own isometric 2D chart, the pieces laid side by side in one plane (the layout) where the catching-up scheme
runs unchanged.

A floor's chart is its plan (x, y). A stair is a plane strip: its chart unfolds it about its foot into the plane
of the floor below, C(P) = P + (sec(theta) - 1) ((P - F) . n) n (F a point of the foot, n the uphill plan
direction, tan(theta) = |grad z|): lengths on the slope are lengths in the chart, and a plan velocity U becomes
A U, A = I + (sec(theta) - 1) n n^T. Across a fold (a stair's foot or head, the edge two pieces share) the two
charts differ by a translation T (0 at the foot, (sec(theta) - 1) l_plan n at the head): the pair of pieces
unfolded along their fold is isometric to the surface there (a developable strip), so a gap across a fold is the
distance in that unfolded plane.

The layout puts piece k's chart at the offset O_k = (k s, 0), s wider than the building: pieces never overlap, so
contacts between discs (and with walls) of different pieces exist only where added here: across a fold, between
the discs within a band of it on either side (half the stair's length), the gap measured with the shift
O_a - O_b - T of the fold (:meth:`Atlas.cross_pairs`); a piece's walls include its neighbours' walls within that
band, moved into its chart. No contact across floors: floors share no fold. A disc whose move crosses a fold goes
into the next piece's chart (:meth:`Atlas.recharted`).
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ..mesh.locate import PointLocator
from .contacts import point_segment_distance
from .crossings import segment_crossings


class StairTooShort(RuntimeError):
    """Contacts that reach further than half a stair: the pairs across its folds would not all be found."""


class Atlas:
    """The charts of a building's pieces (its physical surface groups), their folds and the layout of the discs."""

    def __init__(self, domain):
        self.domain = domain
        pieces = {name: np.asarray(cells) for name, cells in domain.mesh.subdomains.items()
                  if not name.startswith("gmsh:")}
        self.names = list(pieces)
        self.piece_of_cell = np.full(domain.ncells, -1, np.intp)
        for k, cells in enumerate(pieces.values()):
            self.piece_of_cell[cells] = k
        npieces, t = len(self.names), domain.triangles
        slope = np.array([domain.slope[cells].mean(axis=0) for cells in pieces.values()])
        rise = np.hypot(slope[:, 0], slope[:, 1])
        self.slope, self.sec = slope, np.sqrt(1.0 + rise ** 2)
        self.n = np.divide(slope, rise[:, None], out=np.zeros_like(slope), where=rise[:, None] > 0)
        anchor = t[np.array([cells[0] for cells in pieces.values()]), 0]
        self.z0 = domain.z[anchor] - np.einsum("ij,ij->i", slope, domain.points[anchor])   # z = z0 + slope . P
        self.foot = np.zeros((npieces, 2))     # a point of each stair's foot (the fixed line of its chart)
        self._folds = self._fold_facets()
        for (a, b), facets in self._folds.items():
            stair, floor = (a, b) if rise[a] > 0 else (b, a)
            if rise[floor] > 0 or rise[stair] == 0:
                raise ValueError(f"the discs walk on floors joined by stairs: {self.names[a]!r} and "
                                 f"{self.names[b]!r} share an edge but are not a floor and a stair")
            node = domain.mesh.facets[0, facets[0]]
            if domain.z[node] <= domain.z[t[pieces[self.names[stair]]]].min() + 1e-9:   # its foot
                self.foot[stair] = domain.points[node]
        # the layout: the charts side by side
        nodes = np.unique(t * npieces + self.piece_of_cell[:, None])
        node, piece = nodes // npieces, nodes % npieces
        chart = self.chart(domain.points[node], piece)
        low, high = chart[:, 0].min(), chart[:, 0].max()
        self.spacing = 2.0 * (high - low) + 10.0
        self.left = low - 0.25 * self.spacing   # piece k's layout: [left + k s, left + (k + 1) s) in x
        self.offset = np.column_stack([np.arange(npieces) * self.spacing, np.zeros(npieces)])
        self.points = chart + self.offset[piece]
        self.triangles = np.searchsorted(nodes, t * npieces + self.piece_of_cell[:, None])
        self._locator = PointLocator(self.points, self.triangles)
        self.folds = [self._fold(a, b, facets) for (a, b), facets in self._folds.items()]

    def _fold_facets(self) -> dict:
        """The interior facets between two pieces, per pair of pieces (a < b)."""
        f2t, inner = self.domain.f2t, self.domain.interior
        k0 = self.piece_of_cell[f2t[0]]
        k1 = np.where(inner, self.piece_of_cell[np.maximum(f2t[1], 0)], k0)
        between = np.flatnonzero(k0 != k1)
        pair = np.sort(np.column_stack([k0[between], k1[between]]), axis=1)
        return {(int(a), int(b)): between[(pair[:, 0] == a) & (pair[:, 1] == b)] for a, b in np.unique(pair, axis=0)}

    def _fold(self, a, b, facets) -> dict:
        """A fold: its pieces, the shift of its cross pairs, its band, its segment in each piece's layout (that
        piece on its left), the walls of each piece within the band in the other's layout."""
        ends = self.domain.points[self.domain.mesh.facets[:, facets].ravel()]
        direction = ends[1] - ends[0] if len(ends) > 1 else np.array([1.0, 0.0])
        along = ends @ direction
        segment = ends[[np.argmin(along), np.argmax(along)]]   # the fold in plan
        T = self.chart(segment, b) - self.chart(segment, a)    # chart_b - chart_a on the fold: a translation
        stair = a if self.sec[a] > 1 else b
        stair_cells = self.piece_of_cell == stair
        span = self.chart(self.domain.points[self.domain.triangles[stair_cells].ravel()], stair)
        band = 0.5 * float(np.ptp(span @ self.n[stair]))   # half the stair's length
        layout = {}
        cells = self.domain.f2t[:, facets[0]]
        for k in (a, b):
            seg = self.chart(segment, k) + self.offset[k]
            cell = cells[0] if self.piece_of_cell[cells[0]] == k else cells[1]
            inside = self.points[self.triangles[cell]].mean(axis=0)
            (ax, ay), (bx, by) = seg[1] - seg[0], inside - seg[0]
            layout[k] = seg if ax * by - ay * bx > 0 else seg[::-1]
        return {"a": a, "b": b, "shift": self.offset[a] - self.offset[b] - T[0], "band": band, "segment": layout}

    def chart(self, plan, piece):
        """Chart coordinates of plan points on their pieces (no offset): the unfolding of a stair about its foot."""
        plan = np.asarray(plan, float)
        piece = np.broadcast_to(piece, len(plan))
        n, stretch = self.n[piece], (self.sec[piece] - 1.0)
        return plan + (stretch * np.einsum("ij,ij->i", plan - self.foot[piece], n))[:, None] * n

    def piece(self, X) -> np.ndarray:
        """The piece of each layout point."""
        return np.floor((np.asarray(X)[:, 0] - self.left) / self.spacing).astype(np.intp)

    def plan(self, X):
        """Plan points (x, y) of layout points, and their pieces."""
        piece = self.piece(X)
        C = X - self.offset[piece]
        n = self.n[piece]
        return C + ((1.0 / self.sec[piece] - 1.0) * np.einsum("ij,ij->i", C - self.foot[piece], n))[:, None] * n, piece

    def xyz(self, X):
        """(x, y, z) of layout points on the surface."""
        P, piece = self.plan(X)
        return np.column_stack([P, self.z0[piece] + np.einsum("ij,ij->i", self.slope[piece], P)])

    def to_chart(self, U, piece):
        """A U: plan velocities U (n, 2) on their pieces as velocities in the charts (their lift's length)."""
        n = self.n[piece]
        return U + ((self.sec[piece] - 1.0) * np.einsum("ij,ij->i", U, n))[:, None] * n

    def velocity3d(self, X, u):
        """The chart velocities u of the discs at X as vectors in space (their lift onto their piece's plane)."""
        piece = self.piece(X)
        n = self.n[piece]
        U = u + ((1.0 / self.sec[piece] - 1.0) * np.einsum("ij,ij->i", u, n))[:, None] * n
        return np.column_stack([U, np.einsum("ij,ij->i", self.slope[piece], U)])

    def locate(self, X) -> np.ndarray:
        """The cell of the mesh holding each layout point (-1: none)."""
        return self._locator(X)

    def velocity(self, X, cells_U) -> np.ndarray:
        """The chart velocities of the plan velocities per cell `cells_U` at the layout points X (0 outside)."""
        cell = self.locate(X)
        inside = cell >= 0
        U = np.zeros((len(X), 2))
        U[inside] = self.to_chart(cells_U[cell[inside]], self.piece_of_cell[cell[inside]])
        return U

    def counts(self, X) -> np.ndarray:
        """The discs on each piece."""
        return np.bincount(self.piece(X), minlength=len(self.names))

    def segments(self, facets_mask, walls: bool) -> np.ndarray:
        """Layout segments (S, 2, 2) of the facets of a mask, each in its piece's chart; `walls`: with each piece's
        walls within the band of a fold moved into the other piece's chart (walls seen across the fold)."""
        facets = np.flatnonzero(facets_mask)
        piece = self.piece_of_cell[self.domain.f2t[0, facets]]
        ends = self.domain.points[self.domain.mesh.facets[:, facets].T]   # (S, 2, 2)
        own = np.stack([self.chart(ends[:, e], piece) for e in (0, 1)], axis=1) + self.offset[piece][:, None]
        if not walls:
            return own
        out = [own]
        for fold in self.folds:
            for k, other in ((fold["a"], fold["b"]), (fold["b"], fold["a"])):
                mine = own[piece == k]
                band = shapely.buffer(shapely.linestrings(fold["segment"][k]), fold["band"])
                clipped = shapely.intersection(shapely.linestrings(mine), band)
                keep = (shapely.get_type_id(clipped) == 1) & ~shapely.is_empty(clipped)
                if not keep.any():
                    continue
                seg = shapely.get_coordinates(clipped[keep]).reshape(-1, 2, 2)
                # into the other piece's layout: X_other = X_k - shift (k = a) or X_k + shift (k = b)
                out.append(seg - fold["shift"] if k == fold["a"] else seg + fold["shift"])
        return np.concatenate(out)

    def cross_pairs(self, X, reach: float):
        """The disc pairs (i on a, j on b) across each fold within `reach` of each other in the unfolded plane of
        the fold, both within its band, and the shift of each (the gap of a pair: |X_j - X_i + shift| - r_i - r_j)."""
        piece = self.piece(X)
        found = [(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((0, 2)))]
        for fold in self.folds:
            near = {}
            if reach > fold["band"]:
                raise StairTooShort(f"the discs' contacts reach {reach:.3g} m, more than half the stair at the fold "
                                    f"of {self.names[fold['a']]!r} and {self.names[fold['b']]!r} "
                                    f"({fold['band']:.3g} m)")
            for k in (fold["a"], fold["b"]):
                on = np.flatnonzero(piece == k)
                seg = fold["segment"][k]
                _, d = point_segment_distance(X[on], np.broadcast_to(seg[0], (len(on), 2)),
                                              np.broadcast_to(seg[1], (len(on), 2)))
                near[k] = on[d <= fold["band"]]
            i, j = near[fold["a"]], near[fold["b"]]
            if not (len(i) and len(j)):
                continue
            hits = cKDTree(X[i]).query_ball_tree(cKDTree(X[j] + fold["shift"]), reach)
            count = np.array([len(h) for h in hits], np.intp)
            if count.sum():
                pi, pj = np.repeat(i, count), j[np.concatenate([h for h in hits if h]).astype(np.intp)]
                found.append((pi, pj, np.broadcast_to(fold["shift"], (len(pi), 2))))
        return (np.concatenate([f[0] for f in found]), np.concatenate([f[1] for f in found]),
                np.concatenate([f[2] for f in found]))

    def recharted(self, X0, X1):
        """The layout points X1 after moves from X0, those whose move crossed a fold in the next piece's chart, and
        the mask of those."""
        X1 = X1.copy()
        crossed = np.zeros(len(X1), bool)
        for fold in self.folds:
            for k, sign in ((fold["a"], -1.0), (fold["b"], 1.0)):
                over = segment_crossings(X0, X1, fold["segment"][k][None])[:, 0] > 0   # from k's side (the left)
                over &= ~crossed
                X1[over] += sign * fold["shift"]
                crossed |= over
        return X1, crossed
