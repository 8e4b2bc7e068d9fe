"""The one place where the size of a triangle and the gradient of a P1 field are computed."""

import numpy as np


def doubled_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(b - a) x (c - a) for the triangles (a, b, c): twice the signed area (> 0 counter-clockwise)."""
    a, b, c = (points[triangles[:, k], :2] for k in range(3))
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def surface_areas(points, elevation, triangles) -> np.ndarray:
    """The areas of the triangles of a building (docs/floors.md): plan points (n, 2), elevations (n,)."""
    p = np.column_stack([points, elevation])
    a, b, c = (p[triangles[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def surface_edges(points, elevation, triangles) -> np.ndarray:
    """(m, 3): the length on the surface of the edge of each triangle opposite each of its vertices."""
    p = np.column_stack([points, elevation])
    x = p[triangles]
    return np.linalg.norm(np.roll(x, -2, axis=1) - np.roll(x, -1, axis=1), axis=2)


class P1Gradient:
    """The gradient per triangle of the P1 interpolant of nodal values; the triangles' edge vectors kept."""

    def __init__(self, points, triangles):
        p, t = points, triangles
        self.triangles = t
        self.e1, self.e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
        self.det = self.e1[:, 0] * self.e2[:, 1] - self.e1[:, 1] * self.e2[:, 0]

    def __call__(self, d, cells=None) -> np.ndarray:
        """(cells, 2): the gradient in these cells (indices; None: all) of nodal values d (inf where any node is
        inf)."""
        t, e1, e2, det = ((self.triangles, self.e1, self.e2, self.det) if cells is None else
                          (x.take(cells, axis=0) for x in (self.triangles, self.e1, self.e2, self.det)))
        dt = d.take(t)
        with np.errstate(invalid="ignore"):   # inf - inf next to an unreached node: set to inf below
            d1, d2 = dt[:, 1] - dt[:, 0], dt[:, 2] - dt[:, 0]
            gx = (d1 * e2[:, 1] - d2 * e1[:, 1]) / det
            gy = (d2 * e1[:, 0] - d1 * e2[:, 0]) / det
        g = np.column_stack([gx, gy])
        g[~np.all(np.isfinite(dt), axis=1)] = np.inf
        return g
