"""The walkable area of a mesh as a shapely polygon: its outline with the obstacles as holes.

Used to check measurement lines and areas against the domain and written as WKT next to the disc
trajectories (PedPy's ``WalkableArea`` reads it).
"""

import numpy as np
import shapely

from .domain import Domain


def walkable_area(domain: Domain):
    """The union of the faces bounded by the mesh's boundary edges that lie inside the mesh (Polygon or
    MultiPolygon): shapely's polygonize gives every face of the boundary rings, holes included, so the
    faces whose interior point is outside the triangles are dropped."""
    edges = domain.mesh.facets[:, ~domain.interior].T
    lines = shapely.linestrings(domain.points[edges])
    faces = list(shapely.get_parts(shapely.polygonize(lines)))
    inside = [f for f in faces if domain.locate(np.array(f.representative_point().coords))[0] >= 0]
    return shapely.union_all(inside)
