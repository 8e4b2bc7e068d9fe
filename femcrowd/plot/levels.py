"""The floors of a building side by side, for the top views of the pictures (docs/floors.md).

Floors of a building lie above each other in plan: seen from above, the upper floor hides the lower. The
pictures lay them out left to right by elevation, each shifted along x by the building's width and a gap;
a stair is drawn with the floor of its head. The triangles are drawn apart (each with its own three points),
so that a stair's foot may leave the floor below it.
"""

import numpy as np
import pyvista as pv

#: the gap between two floors laid side by side, as a fraction of the building's width
GAP = 0.08


class Levels:
    """The shift along x of every cell and facet of a building's domain, and the views shifted by it."""

    def __init__(self, domain):
        self.domain = domain
        t, z = domain.triangles, domain.z
        pieces = {name: np.asarray(cells) for name, cells in domain.mesh.subdomains.items()}
        level_z = {name: float(z[t[cells]].max()) for name, cells in pieces.items()}   # a stair: its head
        floors = sorted({z_ for name, z_ in level_z.items() if np.ptp(z[t[pieces[name]]]) == 0})
        self.names = [[name for name, cells in pieces.items() if np.ptp(z[t[cells]]) == 0 and level_z[name] == e]
                      for e in floors]
        self.elevations = floors
        width = float(np.ptp(domain.points[:, 0]))
        self.step = width * (1 + GAP)
        level = np.zeros(domain.ncells, int)
        for name, cells in pieces.items():
            level[cells] = int(np.argmin(np.abs(np.array(floors) - level_z[name])))
        self.shift = self.step * level

    def corners(self) -> np.ndarray:
        """(3 n, 2): the corners of the n triangles apart, shifted; triangle k is corners 3 k, 3 k + 1, 3 k + 2."""
        points = self.domain.points[self.domain.triangles].copy()
        points[..., 0] += self.shift[:, None]
        return points.reshape(-1, 2)

    def cells(self, mesh: pv.DataSet) -> pv.PolyData:
        """The triangles of a frame (or of the floor) apart, shifted, at z = 0, with their cell data (the frame's
        points are the domain's, at their elevations)."""
        points = np.column_stack([self.corners(), np.zeros(3 * self.domain.ncells)])
        faces = np.arange(3 * self.domain.ncells).reshape(-1, 3)
        out = pv.PolyData.from_regular_faces(points, faces)
        for name in mesh.cell_data.keys():
            out.cell_data[name] = np.asarray(mesh.cell_data[name])
        return out

    def discs(self, mesh: pv.DataSet) -> pv.DataSet:
        """The discs of a frame (at their (x, y, z)) shifted with their floor, at z = 0: a disc on a stair with the
        floor of the stair's head, the first floor above it."""
        points = np.asarray(mesh.points, float).copy()
        level = np.minimum(np.searchsorted(self.elevations, points[:, 2] - 1e-9), len(self.elevations) - 1)
        points[:, 0] += self.step * level
        points[:, 2] = 0.0
        out = mesh.copy()
        out.points = points
        return out

    def segments(self, facets) -> np.ndarray:
        """Segments (n, 2, 2) of the facets (a mask or indices), shifted with their cell."""
        facets = np.flatnonzero(facets) if np.asarray(facets).dtype == bool else np.asarray(facets)
        segments = self.domain.points[self.domain.mesh.facets[:, facets].T].copy()
        segments[..., 0] += self.shift[self.domain.f2t[0, facets]][:, None]
        return segments

    def captions(self):
        """The point below the middle of each floor's panel and its caption: its name(s) and elevation."""
        (x0, y0), x1 = self.domain.points.min(axis=0), self.domain.points[:, 0].max()
        points = [((x0 + x1) / 2 + k * self.step, y0) for k in range(len(self.names))]
        return points, [f"{', '.join(names)} (z = {z:g} m)" for names, z in zip(self.names, self.elevations)]

    def point(self, facets, xy) -> np.ndarray:
        """A point xy of a group of facets (an exit's label), shifted with the group's first cell."""
        return xy + [self.shift[self.domain.f2t[0, facets[0]]], 0.0]
