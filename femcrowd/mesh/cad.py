"""Floor plans from CAD: DXF drawings (ezdxf) and WKT polygons (JuPedSim's walkable areas, shapely).

A DXF drawing names its parts by layers (the names are options, case-insensitive):

- ``walls`` (default "walls"): the outline of the walkable area, one closed loop made of closed
  polylines, or of lines, arcs and open polylines that join end to end; further closed loops on
  this layer are obstacles;
- ``obstacles`` (default "obstacles"): circles, and closed loops as above;
- exits and entrances: every layer whose name starts with one of the ``doors`` prefixes
  (default "exit" and "entrance") holds named boundary segments on the outline, lines or polylines;
  the group is named after the layer ("exit_east"). A case lists which groups are exits
  (``boundary.exits``) and which are entrances (``[[sources]]``).

A WKT file holds one POLYGON (its holes are the obstacles), as JuPedSim writes walkable areas; its
exits come as extra segments (``femcrowd mesh plan.wkt --exit exit=10,2.5,10,3.5``).

Both become the tables of a TOML floor plan and go through the same checks and meshing
(mesh/plan.py); errors name the layer and the entity (its DXF handle).
"""

import pathlib

import numpy as np

from ..errors import InputError
from .plan import PlanReader, check_plan

DEFAULT_LAYERS = {"walls": "walls", "obstacles": "obstacles", "doors": ("exit", "entrance")}


class _CadReader(PlanReader):
    """Errors of the floor-plan checks, with the table keys translated to the drawing's layers and entities."""

    def __init__(self, file, origins):
        super().__init__(file)
        self.origins = origins

    def error(self, key, value, message):
        for table, origin in sorted(self.origins.items(), key=lambda item: -len(item[0])):
            if key is not None and (key == table or key.startswith(table + ".")):
                return InputError(self.file, origin, _short(value), message)
        return InputError(self.file, key, _short(value), message)


def _short(value):
    """Long point lists are shown by their first points."""
    if isinstance(value, dict):
        value = value.get("points", value.get("circle", value))
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def read_plan(file, walls=None, obstacles=None, doors=None, size=0.2, exits=()):
    """(size, loops, circles, exits, tol) of a DXF or WKT floor plan, as plan.read_toml_plan returns them.

    exits: extra named segments ``[(name, (x0, y0), (x1, y1)), ...]`` (a WKT polygon has none of its own).
    """
    file = pathlib.Path(file)
    try:
        text = file.read_text() if file.suffix.lower() == ".wkt" else None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(file, None, None, f"cannot read the plan: {getattr(err, 'strerror', None) or err}") from None
    if text is not None:
        data, origins = _from_wkt(file, text)
    else:
        layers = {"walls": walls or DEFAULT_LAYERS["walls"], "obstacles": obstacles or DEFAULT_LAYERS["obstacles"],
                  "doors": tuple(doors or DEFAULT_LAYERS["doors"])}
        data, origins = _from_dxf(file, layers, size)
    data["size"] = size
    for name, a, b in exits:
        origins[f"exits[{len(data['exits'])}]"] = f"--exit {name}"
        data["exits"].append({"name": name, "from": list(a), "to": list(b)})
    return check_plan(data, _CadReader(file, origins))


def _from_wkt(file, text):
    import shapely

    try:
        geometry = shapely.from_wkt(text.strip())
    except shapely.errors.GEOSException as err:
        raise InputError(file, None, None, f"not a WKT geometry: {err}") from None
    polygons = [g for g in shapely.get_parts(geometry) if g.geom_type == "Polygon"]
    if len(polygons) != 1:
        raise InputError(file, "POLYGON", geometry.geom_type, "expected one polygon (the walkable area, obstacles "
                         f"as its holes), found {len(polygons)}")
    polygon = polygons[0]
    data = {"outer": {"points": _ring(polygon.exterior.coords)},
            "holes": [{"points": _ring(ring.coords)} for ring in polygon.interiors], "exits": []}
    origins = {"outer": "POLYGON exterior", **{f"holes[{k}]": f"POLYGON hole {k + 1}"
                                               for k in range(len(data["holes"]))}}
    return data, origins


def _ring(coords) -> list:
    """A closed ring's points without the repeated first point."""
    points = [list(map(float, c[:2])) for c in coords]
    return points[:-1] if len(points) > 1 and points[0] == points[-1] else points


def _from_dxf(file, layers, size):
    import ezdxf
    from ezdxf import path as dxfpath

    try:
        doc = ezdxf.readfile(str(file))
    except OSError as err:
        raise InputError(file, None, None, f"cannot read the drawing: {err}") from None
    except ezdxf.DXFError as err:
        raise InputError(file, None, None, f"not a DXF drawing: {err}") from None
    sagitta = size / 20   # arcs become chords no further than this from the arc
    pieces = {"walls": [], "obstacles": [], "doors": []}
    circles = []
    for entity in doc.modelspace():
        layer = entity.dxf.layer
        kind = next((k for k in ("walls", "obstacles") if layer.lower() == layers[k].lower()), None)
        if kind is None and layer.lower().startswith(tuple(p.lower() for p in layers["doors"])):
            kind = "doors"
        if kind is None or entity.dxftype() not in ("LINE", "LWPOLYLINE", "POLYLINE", "ARC", "CIRCLE"):
            continue
        origin = f"layer {layer!r} {entity.dxftype()} #{entity.dxf.handle}"
        if entity.dxftype() == "CIRCLE" and kind == "obstacles":
            circles.append(({"circle": {"center": list(entity.dxf.center)[:2], "radius": entity.dxf.radius}},
                            origin))
            continue
        points = np.array([(v.x, v.y) for v in dxfpath.make_path(entity).flattening(sagitta)])
        closed = entity.dxftype() == "CIRCLE" or getattr(entity, "closed", False) or getattr(entity, "is_closed",
                                                                                              False)
        pieces[kind].append((points, bool(closed), layer.lower(), origin))
    span = np.ptp(np.concatenate([p for p, *_ in pieces["walls"]]), axis=0).max() if pieces["walls"] else 1.0
    tol = 1e-6 * span
    wall_loops = _loops(file, pieces["walls"], tol)
    if not wall_loops:
        raise InputError(file, f"layer {layers['walls']!r}", None, "no outline: the walls layer has no closed loop "
                         "(closed polylines, or lines and arcs joined end to end)")
    areas = [abs(_signed_area(p)) for p, _ in wall_loops]
    outer = int(np.argmax(areas))
    holes = [loop for k, loop in enumerate(wall_loops) if k != outer] + _loops(file, pieces["obstacles"], tol)
    data = {"outer": {"points": wall_loops[outer][0].tolist()},
            "holes": [{"points": p.tolist()} for p, _ in holes] + [c for c, _ in circles], "exits": []}
    origins = {"outer": wall_loops[outer][1]}
    origins.update({f"holes[{k}]": origin for k, (_, origin) in enumerate(holes + [(None, o) for _, o in circles])})
    for points, _, layer, origin in pieces["doors"]:
        for a, b in zip(points[:-1], points[1:]):
            origins[f"exits[{len(data['exits'])}]"] = origin
            data["exits"].append({"name": layer, "from": a.tolist(), "to": b.tolist()})
    return data, origins


def _loops(file, pieces, tol):
    """Closed loops [(points without the repeated first point, origin)] from closed pieces and from open
    pieces joined end to end; an open end left over is an error naming where it is."""
    loops, chains = [], []
    for points, closed, _, origin in pieces:
        if closed or (len(points) > 2 and np.linalg.norm(points[0] - points[-1]) <= tol):
            loops.append((_drop_closing(points, tol), origin))
        else:
            chains.append([points, origin])
    while chains:   # join open pieces: a few entities of a drawing, once
        points, origin = chains.pop()
        while np.linalg.norm(points[0] - points[-1]) > tol:
            k, flip = next(((k, f) for k, (p, _) in enumerate(chains) for f in (False, True)
                            if np.linalg.norm((p[-1] if f else p[0]) - points[-1]) <= tol), (None, None))
            if k is None:
                raise InputError(file, origin, f"({points[-1][0]:g}, {points[-1][1]:g})",
                                 "open outline: nothing joins this end (close the polyline, or join the lines "
                                 "and arcs end to end)")
            piece = chains.pop(k)[0]
            points = np.concatenate([points, (piece[::-1] if flip else piece)[1:]])
        loops.append((_drop_closing(points, tol), origin))
    return loops


def _drop_closing(points, tol):
    return points[:-1] if np.linalg.norm(points[0] - points[-1]) <= tol else points


def _signed_area(p) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(x @ np.roll(y, -1) - y @ np.roll(x, -1))
