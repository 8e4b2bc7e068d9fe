"""Desired velocity U (docs/model.md, "Desired velocity"): what each population would do alone.

Every kind offers the same interface, evaluated for a state (its time t, and its density
for a speed that depends on it) and the exits open at that time:

- ``normal_on_facets(state, exits)``: (2, F) U . n on each facet seen from f2t[0] and from
  f2t[1] (n oriented f2t[0] -> f2t[1]), what the transport needs;
- ``at_points(xy, t, exits)``: (m, 2) at points, for the discs of the micro model;
- ``steady``: True when U changes only with the open exits (the transport is then built once
  per set of open exits);
- ``potential(exits)``: a cell field that decreases downstream, or None (it orders the solves of
  the implicit transport).

Two kinds, chosen by ``[velocity].type``:

- ``field``: U = (ux, uy), expressions in x, y, t. The transport uses U . n at facet
  midpoints; no distance field is computed.
- ``exits``: U = -v grad d / |grad d|, with d the shortest-path distance inside the domain
  to the nearest open exit of those the population heads for (nodal,
  :func:`femcrowd.mesh.distance.exit_distance`, computed once per set of open exits) and grad d
  the P1 gradient per triangle; each facet has the normal velocity of each of its two cells
  (flux splitting, see transport/upwind.py). Where
  d is infinite (no path to any exit) or grad d vanishes, U = 0: people who cannot reach an
  exit stay where they are (but are still pushed by the pressure if their region is saturated).
"""

import numpy as np

from ..mesh.distance import exit_distance


class FieldVelocity:
    """U given by expressions ux(x, y, t), uy(x, y, t)."""

    def __init__(self, domain, ux, uy):
        self.domain, self.ux, self.uy = domain, ux, uy
        self.steady = not (ux.depends_on_time or uy.depends_on_time)

    def at_points(self, xy: np.ndarray, t: float = 0.0, exits=None) -> np.ndarray:
        return np.column_stack([self.ux(xy[:, 0], xy[:, 1], t), self.uy(xy[:, 0], xy[:, 1], t)])

    def potential(self, exits=None):
        return None

    def normal_on_facets(self, state, exits=None) -> np.ndarray:
        """(2, F): U(m_e) . n_e, the same seen from both cells of the facet."""
        a = np.einsum("ij,ij->i", self.at_points(self.domain.midpoint, state.t), self.domain.normal)
        return np.stack([a, a])


class ExitsVelocity:
    """U = -speed grad d/|grad d| from the distance d to the open exits (one field per set of open exits);
    ``targets``: the names of the exits this population heads for (None: all exits)."""

    steady = True

    def __init__(self, domain, speed, targets=None):
        self.domain = domain
        self.speed = speed(domain.centroid[:, 0], domain.centroid[:, 1], 0.0)
        self.targets = None if targets is None else frozenset(targets)
        self._cells = {}  # per set of open target exits
        self.distance = {}

    def cells(self, exits) -> np.ndarray:
        """U per cell for these open exits (the distance field is computed on first use)."""
        heading = self._heading(exits)
        if heading not in self._cells:
            d = self.distance[heading] = exit_distance(self.domain.points, self.domain.triangles,
                                                       self._edges(exits, heading))
            grad = _p1_gradient(self.domain, d)
            if len(heading) > 1:
                self._on_ridges(exits, heading, grad)
            norm = np.hypot(grad[:, 0], grad[:, 1])
            ok = np.isfinite(norm) & (norm > 0)
            cells = np.zeros((self.domain.ncells, 2))
            cells[ok] = -(self.speed[ok] / norm[ok])[:, None] * grad[ok]
            self._cells[heading] = cells
        return self._cells[heading]

    def _on_ridges(self, exits, heading, grad):
        """On the ridges of d between two exits (cells whose nodes are nearest to different exits), the
        gradient of the distance to the cell's own nearest exit, in place.

        There the P1 gradient of d = min_e d_e averages two directions: along the ridge, into a wall where
        two doors share it, and across it back and forth; a thin layer of crowd would stay there for good.
        People on a watershed pick one of the exits: the one nearest to the cell (mean of its nodes)."""
        t = self.domain.triangles
        each = np.stack([exit_distance(self.domain.points, t, self._edges(exits, (name,))) for name in heading])
        nearest = np.argmin(each, axis=0)[t]   # the nearest exit of each node of each cell
        ridge = np.flatnonzero((nearest != nearest[:, :1]).any(axis=1))
        with np.errstate(invalid="ignore"):
            own = np.argmin(each[:, t[ridge]].mean(axis=2), axis=0)
        for e in np.unique(own):
            cells = ridge[own == e]
            grad[cells] = _p1_gradient(self.domain, each[e], cells)

    def _heading(self, exits) -> tuple:
        """The open exits this population heads for."""
        return exits.open if self.targets is None else tuple(n for n in exits.open if n in self.targets)

    def _edges(self, exits, heading):
        """Node pairs of the open exit facets this population heads for."""
        if heading == exits.open:
            return exits.edges()
        wanted = np.isin(exits.group, [exits.names.index(n) for n in heading])
        return self.domain.mesh.facets[:, wanted & exits.exit].T

    def potential(self, exits) -> np.ndarray:
        """The distance to the open exits this population heads for, per cell (mean of its nodes; cells cut
        off from every exit last)."""
        self.cells(exits)
        d = self.distance[self._heading(exits)][self.domain.triangles].mean(axis=1)
        return np.where(np.isfinite(d), d, -1.0)

    def at_points(self, xy: np.ndarray, t: float, exits) -> np.ndarray:
        """U of the triangle containing each point (0 outside the mesh)."""
        cell = self.domain.locate(xy)
        return np.where((cell >= 0)[:, None], self.cells(exits)[np.maximum(cell, 0)], 0.0)

    def normal_on_facets(self, state, exits) -> np.ndarray:
        """(2, F): U_K . n_e for K = f2t[0] and K = f2t[1] (f2t[0] again on the boundary)."""
        k0, k1 = self.domain.f2t
        n, cells = self.domain.normal, self.cells(exits)
        return np.stack([np.einsum("ij,ij->i", cells[k], n) for k in (k0, np.where(k1 >= 0, k1, k0))])


def _p1_gradient(domain, d, cells=slice(None)):
    """Gradient per triangle (of these cells) of the P1 interpolant of nodal values d (inf where any node
    is inf)."""
    p, t = domain.points, domain.triangles[cells]
    e1, e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    with np.errstate(invalid="ignore"):
        d1, d2 = d[t[:, 1]] - d[t[:, 0]], d[t[:, 2]] - d[t[:, 0]]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    gx = (d1 * e2[:, 1] - d2 * e1[:, 1]) / det
    gy = (d2 * e1[:, 0] - d1 * e2[:, 0]) / det
    bad = ~np.all(np.isfinite(d[t]), axis=1)
    g = np.column_stack([gx, gy])
    g[bad] = np.inf
    return g
