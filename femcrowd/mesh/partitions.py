"""Internal walls (partitions) of a floor plan: open polylines inside the outline, cut out of the walkable area.

A partition drawn as a line has no thickness; it is given one (``thickness``, default 0.1 m, a light
partition wall) and the strip it covers is cut out of the walkable area with shapely: the mesh is that of
(outline - holes - partitions), the partitions' sides are ordinary "wall" boundary. A wall of zero thickness
(a curve embedded in the gmsh surface) was not chosen: gmsh's embedded curves make the mesh's edges follow
the line but the cells on its two sides still share those edges, so people, the pressure and the distance
to the exits would pass through it; splitting them takes duplicated nodes (gmsh's Crack plugin), which the
finite-volume geometry, the walkable-area outline (mesh/outline.py) and the disc walls do not expect.

An end of a partition that lies within its thickness of another wall (the outline, a polygon hole, another
partition) is joined to it: extended into it by that distance plus half the thickness, so that no sliver of
a gap is left; any other end is free, cut square where it is drawn, so that a doorway between a free end and
a wall (or between two free ends) keeps its drawn width.
"""

import numpy as np
import shapely

DEFAULT_THICKNESS = 0.1


def cut_partitions(outer, polygons, circles, walls, tol, error):
    """The walkable area's outline and polygon holes once the partitions are cut out of it.

    outer: the outer polygon (n, 2); polygons: the polygon holes; circles: the circle holes (("circle",
    centre, radius)); walls: [(key, points (m, 2), thickness)]; error(key, value, message): the InputError of
    the plan. Returns (outer, polygon holes) as lists of points, each ring without its repeated first point.
    """
    area = shapely.Polygon(outer, polygons)
    inside = shapely.Polygon(outer).buffer(tol)
    lines = [shapely.LineString(p) for _, p, _ in walls]
    discs = [shapely.Point(c).buffer(r) for _, c, r in circles]
    strips = []
    for k, (key, points, thickness) in enumerate(walls):
        if not inside.contains(lines[k]):
            raise error(key, points.tolist(), "the wall must lie inside the outer boundary")
        strip = _strip(points, thickness, shapely.union_all([area.boundary, *lines[:k], *lines[k + 1:]]))
        if any(strip.intersects(d) for d in discs):
            raise error(key, points.tolist(), "the wall touches a circle hole (draw that obstacle as a polygon)")
        strips.append(strip)
    walkable = area.difference(shapely.union_all(strips))
    parts = [g for g in shapely.get_parts(walkable) if g.geom_type == "Polygon" and g.area > tol * area.length]
    if len(parts) != 1:
        sizes = ", ".join(f"{g.area:.3g}" for g in sorted(parts, key=lambda g: -g.area))
        raise error("walls", f"{len(walls)} walls", f"the walls cut the plan into {len(parts)} parts ({sizes} m^2): "
                    "leave a doorway (a gap) in the walls between them")
    ring = parts[0]
    return _points(ring.exterior), [_points(hole) for hole in ring.interiors]


def _strip(points, thickness, rest):
    """The strip a partition covers: its polyline buffered by thickness / 2 with square ends, the ends within
    the thickness of `rest` (the other walls) extended into it."""
    p = points.copy()
    for end, inner in ((0, 1), (-1, -2)):
        gap = shapely.distance(shapely.Point(p[end]), rest)
        if gap <= thickness:
            u = p[end] - p[inner]
            p[end] = p[end] + (gap + thickness / 2) * u / np.linalg.norm(u)
    return shapely.LineString(p).buffer(thickness / 2, cap_style="flat", join_style="mitre")


def _points(ring) -> list:
    return np.asarray(ring.coords)[:-1, :2].tolist()
