"""Mesh and boundaries: the triangulated floor plan and its finite-volume geometry.

A :class:`Domain` wraps a scikit-fem ``MeshTri`` and adds what the DG0 schemes
need, computed once: cell areas, centroids and circumcentres; per facet (edge)
the length, the unit normal oriented from cell ``f2t[0]`` to cell ``f2t[1]``
(outward on the boundary), whether it is an exit or a wall; and the two-point
transmissibilities T_e = |e| / d_e of the pressure Laplacian (design note,
"Discrete spaces"). Every boundary facet that is not in a named exit group is
a wall; holes in the mesh are obstacles.
"""

import difflib
import hashlib
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import skfem

from .errors import InputError

#: d_e is clipped from below at this fraction of the centroid distance (see transmissibility).
CLIP_FRACTION = 0.02


class Domain:
    """The floor plan: a MeshTri, its exits, and the geometry of cells and facets."""

    def __init__(self, mesh, exits=(), source=None):
        self.mesh = mesh
        self.source = source
        self.points = np.ascontiguousarray(mesh.p.T)
        self.triangles = np.ascontiguousarray(mesh.t.T)
        self.exit_names = list(exits)
        p, t = self.points, self.triangles
        a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
        cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
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

        self.exit = np.zeros(mesh.nfacets, bool)
        self.exit_group = {}
        for name in self.exit_names:
            facets = np.asarray(mesh.boundaries[name])
            self.exit_group[name] = facets
            self.exit[facets] = True
        self.wall = ~self.interior & ~self.exit
        self.transmissibility, self.non_delaunay, self.clipped = self._transmissibility()

    @property
    def ncells(self):
        return len(self.triangles)

    @property
    def h(self):
        """Largest facet length (the mesh size of convergence studies)."""
        return float(self.length.max())

    def exit_edges(self):
        """Node pairs (E, 2) of the exit facets."""
        return self.mesh.facets[:, self.exit].T

    def boundary_segments(self, which):
        """Segments (n, 2, 2) of the 'wall' or 'exit' facets (for the disc model)."""
        mask = self.wall if which == "wall" else self.exit
        return self.points[self.mesh.facets[:, mask].T]

    def _transmissibility(self):
        """T_e = |e| / d_e on interior and exit facets, 0 on walls.

        d_e is the signed distance between the circumcentres of the two cells
        along the normal (to the exit edge for exit facets). It is positive on a
        Delaunay pair and negative on a non-Delaunay one (obtuse angles facing
        the edge), where T_e < 0 would break the M-matrix property that makes the
        projection exact and bound preserving. We therefore clip d_e from below
        at CLIP_FRACTION times the (always positive) centroid distance along the
        normal: the M-matrix is kept, the few affected pairs are counted and
        reported, and consistency is lost only on those pairs.
        """
        k0, k1 = self.f2t[0], np.where(self.interior, self.f2t[1], self.f2t[0])
        far_cc = np.where(self.interior[:, None], self.circumcentre[k1], self.midpoint)
        far_g = np.where(self.interior[:, None], self.centroid[k1], self.midpoint)
        d_cc = np.einsum("ij,ij->i", far_cc - self.circumcentre[k0], self.normal)
        d_g = np.einsum("ij,ij->i", far_g - self.centroid[k0], self.normal)
        used = ~self.wall
        floor = CLIP_FRACTION * d_g
        clipped = used & (d_cc < floor)
        d = np.where(clipped, floor, d_cc)
        T = np.where(used, self.length / np.where(used, d, 1.0), 0.0)
        return T, int(np.count_nonzero(used & (d_cc < 0))), int(np.count_nonzero(clipped))

    def laplacian(self):
        """The two-point (negative) Laplacian A (M-matrix, CSR): (A phi)_K = sum_e T_e (phi_K - phi_L),
        with phi_L = 0 across exit facets and no flux across walls."""
        f = ~self.wall
        k0, k1, T = self.f2t[0][f], self.f2t[1][f], self.transmissibility[f]
        inner = k1 >= 0
        rows = np.concatenate([k0, k1[inner], k0[inner], k1[inner]])
        cols = np.concatenate([k0, k1[inner], k1[inner], k0[inner]])
        vals = np.concatenate([T, T[inner], -T[inner], -T[inner]])
        n = self.ncells
        return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))

    def statistics(self):
        """Mesh statistics for summary.json and `femcrowd info`."""
        groups = {name: float(self.length[np.asarray(f)].sum())
                  for name, f in (self.mesh.boundaries or {}).items()
                  if not name.startswith("gmsh:")}
        return {
            "nodes": int(self.mesh.nvertices), "triangles": self.ncells,
            "h_max": self.h, "h_min": float(self.length.min()),
            "area": float(self.area.sum()), "min_cell_area": float(self.area.min()),
            "boundary_groups": groups, "exit_length": float(self.length[self.exit].sum()),
            "non_delaunay_pairs": self.non_delaunay, "clipped_transmissibilities": self.clipped,
        }


def _circumcentres(a, b, c, cross):
    """Circumcentres of triangles (a, b, c); cross = (b - a) x (c - a) = 2 * signed area."""
    ba, ca = b - a, c - a
    nb, nc = (ba ** 2).sum(1), (ca ** 2).sum(1)
    ux = (ca[:, 1] * nb - ba[:, 1] * nc) / (2 * cross)
    uy = (ba[:, 0] * nc - ca[:, 0] * nb) / (2 * cross)
    return a + np.column_stack([ux, uy])


def load_domain(file, exits=(), refine=0, case_file="case.toml"):
    """Read a gmsh mesh (2.2 or 4.1) into a Domain; errors name the case key."""
    path = Path(file)
    if not path.is_file():
        raise InputError(case_file, "mesh.file", str(file), "mesh file not found")
    try:
        mesh = skfem.MeshTri.load(str(path))
    except Exception as err:  # meshio/skfem raise many types for malformed files
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise InputError(case_file, "mesh.file", str(file),
                         f"cannot read a triangle mesh: {message}") from None
    if mesh.t.shape[1] == 0:
        raise InputError(case_file, "mesh.file", str(file), "the mesh has no triangles")
    if not np.all(np.isfinite(mesh.p)):
        raise InputError(case_file, "mesh.file", str(file), "the mesh has non-finite node coordinates")
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
    mesh = mesh.refined(int(refine)) if refine else mesh
    domain = Domain(mesh, exits, source=path)
    if np.any(domain.area <= 0):
        raise InputError(case_file, "mesh.file", str(file), "the mesh has degenerate (zero-area) triangles")
    return domain


def file_checksum(path):
    """sha256 of a file (recorded with the run so that it can be reproduced)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
