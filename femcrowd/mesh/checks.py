"""Checks of a mesh at load time (docs/case-format.md, "Meshes"): what would make a run silently wrong.

- degenerate triangles (height under DEGENERATE x their longest side): no finite-volume geometry;
- inverted triangles (nodes turning the other way from the rest of the mesh: a folded mesh, whose
  triangles overlap, counted with their absolute area);
- cracks: boundary edges on each other (a line of duplicated nodes) in no named line group, which would be
  an unnamed wall through the floor plan;
- the regions of the floor plan: the connected components of the cells through their shared facets
  (what the people of a region can reach; driver/remaining.py judges them against the exits).

Each check is a few vectorised passes over the triangles or the boundary nodes.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .triangles import doubled_areas

#: a triangle whose height is under this fraction of its longest side is degenerate (its circumcentre
#: lies ~1/DEGENERATE sides away; shipped meshes have at least 0.04)
DEGENERATE = 1e-8
#: boundary nodes closer than this fraction of the shortest edge are at one place (a duplicated node)
COINCIDENT = 1e-6


def check_triangles(points: np.ndarray, triangles: np.ndarray, fail) -> None:
    """fail(message) on degenerate triangles, then on triangles oriented against the majority (in the
    file's node order: scikit-fem reorders the nodes of each triangle)."""
    twice = doubled_areas(points, triangles)
    corners = points[triangles, :2]
    longest = (((np.roll(corners, -1, axis=1) - corners) ** 2).sum(-1)).max(axis=1)
    degenerate = np.abs(twice) <= DEGENERATE * longest
    if degenerate.any():
        fail(f"the mesh has {np.count_nonzero(degenerate)} degenerate (zero-area) triangles, whose height is under "
             f"{DEGENERATE:g} of their longest side (first at {_at(corners[degenerate].mean(axis=1))})")
    negative = twice < 0
    inverted = negative if 2 * np.count_nonzero(negative) <= len(twice) else ~negative
    if inverted.any():
        fail(f"the mesh has {np.count_nonzero(inverted)} inverted triangles, their nodes turning the other way from "
             f"the other {len(twice) - np.count_nonzero(inverted)} (a folded mesh; first at "
             f"{_at(corners[inverted].mean(axis=1))})")


def check_cracks(mesh, fail) -> None:
    """fail(message) when boundary edges lie on other boundary edges (their nodes duplicated: a crack) and none
    of them is in a named line group: an unnamed wall through the floor plan. A named one is a wall on purpose
    (a partition cut into the mesh, gmsh's Crack plugin). The nearby nodes come from a k-d tree over the
    boundary nodes only."""
    boundary = np.flatnonzero(mesh.f2t[1] < 0)
    facets = mesh.facets[:, boundary]
    nodes = np.unique(facets)
    xy = mesh.p[:, nodes].T
    edges = mesh.p[:, mesh.facets[0]] - mesh.p[:, mesh.facets[1]]
    pairs = cKDTree(xy).query_pairs(COINCIDENT * np.hypot(*edges).min(), output_type="ndarray")
    if len(pairs) == 0:
        return
    # nodes at one place get one representative; boundary facets whose ends share theirs lie on each other
    _, place = connected_components(sp.coo_matrix((np.ones(len(pairs)), pairs.T), shape=(len(nodes),) * 2))
    ends = np.sort(place[np.searchsorted(nodes, facets)], axis=0)
    _, group, count = np.unique(ends[0] * len(nodes) + ends[1], return_inverse=True, return_counts=True)
    named = np.isin(boundary, np.concatenate([np.zeros(0, int), *[f for name, f in (mesh.boundaries or {}).items()
                                                                 if not name.startswith("gmsh:")]]))
    crack = (count[group] > 1) & ~(np.bincount(group, named) > 0)[group]
    if crack.any():
        xy = mesh.p[:, facets[:, crack]].reshape(2, -1)
        fail(f"the mesh has a crack: {np.count_nonzero(crack)} boundary edges lie on each other "
             f"(duplicated nodes), from {_at(xy.min(axis=1))} to {_at(xy.max(axis=1))}, in no named line group: an "
             "unnamed wall (merge the nodes, e.g. gmsh's Coherence, or name the group if it is a wall)")


def check_pieces(mesh, tol, fail) -> None:
    """fail(message) unless the mesh of a building (its elevations mesh.z) is made of plane pieces: every triangle
    in a named physical surface (a floor or a stair), and z an affine function of (x, y) on each (docs/floors.md)."""
    pieces = {name: cells for name, cells in (mesh.subdomains or {}).items() if not name.startswith("gmsh:")}
    covered = np.zeros(mesh.t.shape[1], bool)
    for name, cells in pieces.items():
        covered[cells] = True
        nodes = np.unique(mesh.t[:, cells])
        plane = np.column_stack([mesh.p[:, nodes].T, np.ones(len(nodes))])
        coefficients = np.linalg.lstsq(plane, mesh.z[nodes], rcond=None)[0]
        off = np.abs(plane @ coefficients - mesh.z[nodes]).max()
        if off > tol:
            fail(f"the mesh is not planar: z varies off a plane by {off:.3g} on the surface group {name!r}; a building "
                 "is made of plane floors and stairs, each a named surface (femcrowd mesh of a building plan)")
    if not covered.all():
        fail(f"the mesh is not planar (z varies) and {np.count_nonzero(~covered)} triangles are in no named surface "
             "group: a building's triangles each belong to a floor or a stair (femcrowd mesh of a building plan)")


def regions(f2t: np.ndarray, ncells: int) -> tuple[int, np.ndarray]:
    """The connected components of the cells through their interior facets: (count, region of each cell)."""
    inner = f2t[1] >= 0
    graph = sp.coo_matrix((np.ones(np.count_nonzero(inner)), (f2t[0][inner], f2t[1][inner])), shape=(ncells,) * 2)
    return connected_components(graph, directed=False)


def _at(xy) -> str:
    x, y = np.atleast_2d(xy)[0]
    return f"({x:.4g}, {y:.4g})"
