"""The floor plan as finite-volume geometry: cells, facets, normals, two-point transmissibilities.

A :class:`Domain` wraps a scikit-fem ``MeshTri`` and adds what the DG0 schemes
need, computed once: cell areas, centroids and circumcentres; per facet (edge)
the length and the unit normal oriented from cell ``f2t[0]`` to cell ``f2t[1]``
(outward on the boundary); the named boundary groups, and among them the
exits of the case; and the two-point transmissibilities T_e = |e| / d_e of the
pressure Laplacian (Eymard, Gallouet, Herbin 2000, "Finite volume methods",
sec. 9: the circumcentres of a Delaunay mesh are the admissible cell centres).
Which exits are open at a time t is not a property of the floor plan: see
:mod:`femcrowd.mesh.boundary`. Holes in the mesh are obstacles.

A building (docs/floors.md: a mesh with elevations ``z``, plane floors and stairs) keeps its plan (x, y) as
``points``, ``centroid``, ``midpoint`` and ``normal``, and measures on the surface what the operators weigh: the
cell areas, the facet lengths, the circumcentre distances of T_e; ``lift`` (2, F) turns a plan velocity's flux
U . n into the flux through the facet on the surface (the Piola identity of the lift of a plane piece), and
``slope`` is grad z per cell (the metric I + slope slope^T of each piece).
"""

import difflib
from functools import cached_property
from pathlib import Path

import numpy as np

from ..errors import InputError, not_a_file
from .checks import regions
from .gmsh_io import read_mesh
from .locate import PointLocator
from .triangles import P1Gradient, doubled_areas, surface_areas

#: d_e is clipped from below at this fraction of the centroid distance (see _transmissibility).
CLIP_FRACTION = 0.02


class Domain:
    """The floor plan: a MeshTri, its named boundary groups and exits, the geometry of cells and facets.

    ``exit_group`` maps each exit of the case (``boundary.exits``, in that order) to its facets;
    every other boundary facet is a wall.
    """

    def __init__(self, mesh, exits=(), source=None):
        self.mesh = mesh
        self.source = source
        self.points = np.ascontiguousarray(mesh.p.T)
        self.triangles = np.ascontiguousarray(mesh.t.T)
        p, t = self.points, self.triangles
        a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
        cross = doubled_areas(p, t)
        self.area = 0.5 * np.abs(cross)
        self.centroid = (a + b + c) / 3.0
        self.circumcentre = _circumcentres(a, b, c, cross)

        self.f2t = mesh.f2t
        self.interior = self.f2t[1] >= 0
        fa, fb = p[mesh.facets[0]], p[mesh.facets[1]]
        tangent = fb - fa
        self.length = np.hypot(tangent[:, 0], tangent[:, 1])
        self.midpoint = 0.5 * (fa + fb)
        normal = np.column_stack([tangent[:, 1], -tangent[:, 0]]) / self.length[:, None]
        flip = np.einsum("ij,ij->i", self.midpoint - self.centroid[self.f2t[0]], normal) < 0
        normal[flip] *= -1
        self.normal = normal

        self.z = getattr(mesh, "z", None)
        self.lift = self.slope = None
        if self.z is not None:
            self._on_surface()

        self.groups = {name: np.asarray(f) for name, f in (mesh.boundaries or {}).items()
                       if not name.startswith("gmsh:")}
        self.exit_names = list(exits)
        self.exit_group = {name: self.groups[name] for name in self.exit_names}
        self.transmissibility, self.non_delaunay, self.clipped = self._transmissibility()
        self._locator = None

    def _on_surface(self):
        """The geometry of a building measured on its surface (module docstring); the plan kept for the rest."""
        plan_area, plan_length = self.area, self.length
        t, facets = self.triangles, self.mesh.facets
        xyz = np.column_stack([self.points, self.z])
        a, b, c = xyz[t[:, 0]], xyz[t[:, 1]], xyz[t[:, 2]]
        self.area = surface_areas(self.points, self.z, t)
        self.length = np.linalg.norm(xyz[facets[1]] - xyz[facets[0]], axis=1)
        self.slope = P1Gradient(self.points, t)(self.z)
        k1 = np.where(self.interior, self.f2t[1], self.f2t[0])
        stretch = self.area / plan_area
        self.lift = np.stack([stretch[k] * plan_length / self.length for k in (self.f2t[0], k1)])
        self.surface_circumcentre = _circumcentres_3d(a, b, c)
        self.surface_centroid = (a + b + c) / 3.0

    def _surface_distances(self):
        """Per facet the distances (circumcentres, centroids) between its two cells measured across the facet on
        the surface: the sum of each cell's distance to the facet's line in its own plane, signed positive on the
        cell's side (the one cell's and the facet for an exit facet), as the plan's d_e along the normal."""
        xyz = np.column_stack([self.points, self.z])
        start, end = xyz[self.mesh.facets[0]], xyz[self.mesh.facets[1]]
        tangent = (end - start) / self.length[:, None]

        def across(point, cell):   # signed distance of point to the facet's line, in the plane of cell
            off = point - start
            off -= np.einsum("ij,ij->i", off, tangent)[:, None] * tangent
            inside = self.surface_centroid[cell] - start
            inside -= np.einsum("ij,ij->i", inside, tangent)[:, None] * tangent
            return np.linalg.norm(off, axis=1) * np.sign(np.einsum("ij,ij->i", off, inside))

        k0, k1 = self.f2t[0], self.f2t[1]
        other = np.maximum(k1, 0)
        inner = self.interior
        d_cc = across(self.surface_circumcentre[k0], k0) + inner * across(self.surface_circumcentre[other], other)
        d_g = across(self.surface_centroid[k0], k0) + inner * across(self.surface_centroid[other], other)
        return d_cc, d_g

    @property
    def ncells(self) -> int:
        return len(self.triangles)

    @property
    def h(self) -> float:
        """Largest facet length (the mesh size of convergence studies)."""
        return float(self.length.max())

    @cached_property
    def gradient(self) -> P1Gradient:
        """The gradient per cell of P1 fields at the nodes: ``domain.gradient(d, cells)``."""
        return P1Gradient(self.points, self.triangles)

    @cached_property
    def region(self) -> np.ndarray:
        """The region of each cell: the connected parts of the floor plan, 0, 1, ... (mesh/checks.py)."""
        return regions(self.f2t, self.ncells)[1]

    def cell_average(self, f, divisions=4, t=0.0):
        """Mean of f(x, y, t) over each cell: midpoint rule on the divisions^2 congruent
        sub-triangles (robust for the discontinuous data of crowd scenes)."""
        lam = []
        for i in range(divisions):
            for j in range(divisions - i):
                lam.append(((i + 1 / 3) / divisions, (j + 1 / 3) / divisions))      # upward
                if i + j < divisions - 1:
                    lam.append(((i + 2 / 3) / divisions, (j + 2 / 3) / divisions))  # downward
        lam = np.array(lam)
        a, b, c = (self.points[self.triangles[:, k]] for k in range(3))
        pts = a[:, None] + lam[None, :, :1] * (b - a)[:, None] + lam[None, :, 1:] * (c - a)[:, None]
        return f(pts[..., 0], pts[..., 1], t).mean(axis=1)

    def locate(self, xy: np.ndarray) -> np.ndarray:
        """Index of the cell containing each point (n, 2), -1 outside the domain."""
        if self._locator is None:
            self._locator = PointLocator(self.points, self.triangles)
        return self._locator(xy)

    def _transmissibility(self):
        """T_e = |e| / d_e on interior facets and on the facets of the exits (open or not), 0 on walls.

        d_e is the signed distance between the circumcentres of the two cells
        along the normal (to the exit edge for exit facets). It is positive on a
        Delaunay pair and negative on a non-Delaunay one (obtuse angles facing
        the edge), where T_e < 0 would break the M-matrix property that makes the
        projection exact and bound preserving. We therefore clip d_e from below
        at CLIP_FRACTION times the (always positive) centroid distance along the
        normal: the M-matrix is kept, the few affected pairs are counted and
        reported, and consistency is lost only on those pairs.
        """
        if self.z is None:
            k0, k1 = self.f2t[0], np.where(self.interior, self.f2t[1], self.f2t[0])
            far_cc = np.where(self.interior[:, None], self.circumcentre[k1], self.midpoint)
            far_g = np.where(self.interior[:, None], self.centroid[k1], self.midpoint)
            d_cc = np.einsum("ij,ij->i", far_cc - self.circumcentre[k0], self.normal)
            d_g = np.einsum("ij,ij->i", far_g - self.centroid[k0], self.normal)
        else:
            d_cc, d_g = self._surface_distances()
        used = self.interior.copy()
        for facets in self.exit_group.values():
            used[facets] = True
        floor = CLIP_FRACTION * d_g
        clipped = used & (d_cc < floor)
        d = np.where(clipped, floor, d_cc)
        T = np.where(used, self.length / np.where(used, d, 1.0), 0.0)
        return T, int(np.count_nonzero(used & (d_cc < 0))), int(np.count_nonzero(clipped))

    def statistics(self) -> dict:
        """Mesh statistics for summary.json and `femcrowd info` (angles on the surface of a building)."""
        x = self.points[self.triangles] if self.z is None else np.column_stack([self.points, self.z])[self.triangles]
        u, v = np.roll(x, -1, axis=1) - x, np.roll(x, 1, axis=1) - x  # the two edges at each corner
        if self.z is None:
            angles = np.arctan2(np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]), (u * v).sum(-1))
        else:
            angles = np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), (u * v).sum(-1))
        groups = {name: float(self.length[f].sum()) for name, f in self.groups.items()}
        exit_facets = np.unique(np.concatenate([np.zeros(0, np.intp), *self.exit_group.values()]))
        return {
            "nodes": int(self.mesh.nvertices), "triangles": self.ncells,
            "h_max": self.h, "h_min": float(self.length.min()),
            "area": float(self.area.sum()), "min_cell_area": float(self.area.min()),
            "min_angle_deg": float(np.degrees(angles.min())), "max_angle_deg": float(np.degrees(angles.max())),
            "boundary_groups": groups, "exit_length": float(self.length[exit_facets].sum()),
            "non_delaunay_pairs": self.non_delaunay, "clipped_transmissibilities": self.clipped,
        }


def _circumcentres(a, b, c, cross):
    """Circumcentres of triangles (a, b, c); cross = (b - a) x (c - a) = 2 * signed area."""
    ba, ca = b - a, c - a
    nb, nc = (ba ** 2).sum(1), (ca ** 2).sum(1)
    ux = (ca[:, 1] * nb - ba[:, 1] * nc) / (2 * cross)
    uy = (ba[:, 0] * nc - ca[:, 0] * nb) / (2 * cross)
    return a + np.column_stack([ux, uy])


def _circumcentres_3d(a, b, c):
    """Circumcentres of triangles (a, b, c) in space: a + (|u|^2 v - |v|^2 u) x (u x v) / (2 |u x v|^2)."""
    u, v = b - a, c - a
    w = np.cross(u, v)
    top = np.cross((u * u).sum(1)[:, None] * v - (v * v).sum(1)[:, None] * u, w)
    return a + top / (2 * (w * w).sum(1))[:, None]


def load_domain(file, exits=(), refine=0, case_file="case.toml", check=None) -> Domain:
    """Read a gmsh mesh (2.2 or 4.1) into a Domain with these exit groups; errors name the case key.

    check: called with the number of triangles the refined mesh will have, before refining (a run's
    estimate, driver/limits.py, refuses a mesh that would not fit in memory)."""
    path = Path(file)
    if not path.is_file():
        raise InputError(case_file, "mesh.file", str(file), not_a_file(path, "mesh file"))
    mesh = read_mesh(path, case_file)
    names = [n for n in (mesh.boundaries or {}) if not n.startswith("gmsh:")]
    for name in exits:
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise InputError(case_file, "boundary.exits", name,
                             f"no boundary group of that name in {path.name} "
                             f"({hint}groups: {', '.join(names) or 'none'})")
        facets = np.asarray(mesh.boundaries[name])
        if len(facets) and np.any(mesh.f2t[1, facets] >= 0):
            raise InputError(case_file, "boundary.exits", name,
                             f"group {name!r} in {path.name} contains interior edges, "
                             "not boundary edges")
    if check is not None:
        check(mesh.t.shape[1] * 4 ** int(refine))   # a uniform refinement splits each triangle in 4
    if refine and mesh.z is None:
        mesh = mesh.refined(int(refine))
    elif refine:
        z = mesh.z
        for _ in range(int(refine)):
            z = None if z is None else np.concatenate([z, z[mesh.facets].mean(axis=0)])   # skfem: midpoints last
            mesh = mesh.refined()
            mesh.z = z
    return Domain(mesh, exits, source=path)
