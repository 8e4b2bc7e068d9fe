"""Floor plans from CAD: DXF drawings (ezdxf) and WKT polygons (JuPedSim's walkable areas, shapely).

A DXF drawing names its parts by layers (the names are options, case-insensitive; docs/plans.md):

- ``walls`` (default "walls"): the outline of the walkable area, one closed loop made of closed
  polylines, or of lines, arcs and open polylines that join end to end; further closed loops on
  this layer are obstacles; lines and open polylines with a free end (nothing else on the layer ends there:
  a partition, whose other end may lie anywhere on the outline or on another partition) are internal walls
  (mesh/partitions.py);
- ``obstacles`` (default "obstacles"): circles, and closed loops as above;
- exits and entrances: every layer whose name starts with one of the ``doors`` prefixes
  (default "exit" and "entrance") holds named boundary segments on the outline, lines or polylines;
  the group is named after the layer ("exit_east"); a group named entrance* is an entrance;
- interior doors: every layer whose name starts with the ``interior`` prefix (default "doors") holds
  lines or polylines inside the plan (a door between two rooms), named after the layer as exits are
  ("doors_ab"): the ``[[doors]]`` of a TOML plan, line groups of interior edges that take a capacity.

An ARC on the walls layer that ends up among the internal walls (not in a closed loop: not a rounded corner
of the outline or of an obstacle) is most likely a door swing drawn on the wrong layer; it is kept as a wall,
which closes the doorway it spans, and a warning names it and where it ends.

Lengths are converted to metres: the drawing's units are ``units`` if given, else its header's
``$INSUNITS`` (unitless or absent: metres; a code ezdxf cannot convert is refused). Layers of other names, and
entities of other kinds, are listed in one warning.

A WKT file holds one POLYGON (its holes are the obstacles), as JuPedSim writes walkable areas, and
optionally LINESTRINGs (internal walls) beside it in a GEOMETRYCOLLECTION; its exits come as extra segments
(``femcrowd mesh plan.wkt --exit exit=10,2.5,10,3.5``), in metres unless ``units`` says otherwise.

Both become the tables of a TOML floor plan and go through the same checks and meshing
(mesh/plan.py); errors name the layer and the entity (its DXF handle).
"""

import logging
import pathlib
from collections import Counter

import numpy as np

from ..errors import InputError
from .plan import PLAUSIBLE, PlanReader, check_plan, is_entrance

log = logging.getLogger("femcrowd")
DEFAULT_LAYERS = {"walls": "walls", "obstacles": "obstacles", "doors": ("exit", "entrance"), "interior": "doors"}
#: --units: the names of the DXF header's $INSUNITS codes (ezdxf.units) that a plan may be drawn in
UNITS = {"mm": 4, "cm": 5, "dm": 14, "m": 6, "km": 7, "in": 1, "ft": 2, "yd": 10}
KINDS = ("LINE", "LWPOLYLINE", "POLYLINE", "ARC", "CIRCLE")


class _CadReader(PlanReader):
    """Errors of the floor-plan checks, with the table keys translated to the drawing's layers and entities."""

    def __init__(self, file, origins, units, require_exits, no_exits_hint):
        super().__init__(file, require_exits)
        self.origins, self.units, self.no_exits_hint = origins, units[0], no_exits_hint
        self.factor = units[1]

    def error(self, key, value, message):
        for table, origin in sorted(self.origins.items(), key=lambda item: -len(item[0])):
            if key is not None and (key == table or key.startswith(table + ".")):
                return InputError(self.file, origin, _short(value), message)
        return InputError(self.file, key, _short(value), message)

    def units_hint(self, extent):
        """The first of mm, cm, m, in, ft that makes the plan plausible, as a --units to try."""
        from ezdxf.units import conversion_factor

        drawn = extent / self.factor
        fits = [u for u in ("mm", "cm", "m", "in", "ft")
                if PLAUSIBLE[0] <= drawn * conversion_factor(UNITS[u], UNITS["m"]) <= PLAUSIBLE[1]
                and not self.units.startswith(u + " ")]
        return ("; give the drawing's units with --units " + fits[0] if fits else
                "; give the drawing's units with --units (" + ", ".join(UNITS) + ")")


def _short(value):
    """Long point lists are shown by their first points."""
    if isinstance(value, dict):
        value = value.get("points", value.get("circle", value))
    text = repr(value)
    return value if len(text) <= 60 else text[:57] + "..."


def read_plan(file, walls=None, obstacles=None, doors=None, size=0.2, exits=(), units=None, wall_thickness=None,
              require_exits=False, interior=None):
    """(size, loops, circles, exits, tol, doors) of a DXF or WKT floor plan, as plan.read_toml_plan returns them.

    exits: extra named segments ``[(name, (x0, y0), (x1, y1)), ...]`` (a WKT polygon has none of its own), in
    the plan's units; units: the drawing's length unit (a key of UNITS; None: the DXF's $INSUNITS, metres for
    WKT); wall_thickness: of the internal walls (m, default mesh/partitions.py); require_exits: a plan without
    an exit is an error; walls, obstacles: the DXF's layers; doors: the prefixes of its exit and entrance
    layers; interior: the prefix of its interior door layers.
    """
    file = pathlib.Path(file)
    if units is not None and units not in UNITS:
        raise InputError(file, "--units", units, f"expected one of {', '.join(UNITS)}")
    try:
        text = file.read_text() if file.suffix.lower() == ".wkt" else None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(file, None, None, f"cannot read the plan: {getattr(err, 'strerror', None) or err}") from None
    if text is not None:
        unit = _unit(file, units, None) if units else ("m (a WKT plan's default)", 1.0)
        data, origins = _from_wkt(file, text, unit[1])
        hint = "give the exits with --exit NAME=X0,Y0,X1,Y1, or --no-exits for a plan nobody leaves"
    else:
        layers = {"walls": walls or DEFAULT_LAYERS["walls"], "obstacles": obstacles or DEFAULT_LAYERS["obstacles"],
                  "doors": tuple(doors or DEFAULT_LAYERS["doors"]), "interior": interior or DEFAULT_LAYERS["interior"]}
        data, origins, unit, names = _from_dxf(file, layers, size, units)
        exit_layers = [p for p in layers["doors"] if not is_entrance(p)] or ["exit"]
        hint = (f"no layer named {'*, '.join(exit_layers)}* holds a line (the drawing's layers: "
                f"{', '.join(names)}); rename the exit layer, give its name with --door-layers, or give --no-exits "
                "for a plan nobody leaves")
    data["size"] = size
    for name, a, b in exits:
        origins[f"exits[{len(data['exits'])}]"] = f"--exit {name}"
        data["exits"].append({"name": name, "from": (np.array(a) * unit[1]).tolist(),
                              "to": (np.array(b) * unit[1]).tolist()})
    if wall_thickness is not None:
        for wall in data["walls"]:
            wall["thickness"] = wall_thickness
    return check_plan(data, _CadReader(file, origins, unit, require_exits, hint))


def _unit(file, name, code):
    """(description, metres per drawing unit) of the --units name, or else of the $INSUNITS code: 0 (unitless)
    taken as metres, the others converted with ezdxf's table (ezdxf.units); a code it has no factor for (8
    microinches, 9 mils, 21-24 the US survey units) or that is no DXF unit is refused, naming it."""
    from ezdxf.units import InsertUnits, conversion_factor

    if name is not None:
        return f"{name} (--units)", conversion_factor(UNITS[name], UNITS["m"])
    if code == 0:
        return "m ($INSUNITS = 0, unitless: taken as m)", 1.0
    hint = f"give the drawing's units with --units ({', '.join(UNITS)})"
    try:
        unit = InsertUnits(code).name
    except ValueError:
        raise InputError(file, "$INSUNITS", code, f"not a DXF unit code; {hint}") from None
    try:
        factor = conversion_factor(code, UNITS["m"])
    except TypeError:
        raise InputError(file, "$INSUNITS", code, f"{unit}: ezdxf.units has no factor to metres; {hint}") from None
    label = next((u for u, c in UNITS.items() if c == code), unit.lower())
    return f"{label} ($INSUNITS = {code})", factor


def _from_wkt(file, text, factor):
    import shapely

    try:
        geometry = shapely.from_wkt(text.strip())
    except shapely.errors.GEOSException as err:
        raise InputError(file, None, None, f"not a WKT geometry: {err}") from None
    parts = list(shapely.get_parts(shapely.get_parts(geometry)))   # a collection's parts, and theirs
    polygons = [g for g in parts if g.geom_type == "Polygon"]
    if len(polygons) != 1:
        raise InputError(file, "POLYGON", geometry.geom_type, "expected one polygon (the walkable area, obstacles "
                         f"as its holes), found {len(polygons)}")
    polygon = shapely.affinity.scale(polygons[0], factor, factor, origin=(0, 0))
    lines = [shapely.affinity.scale(g, factor, factor, origin=(0, 0)) for g in parts if g.geom_type == "LineString"]
    data = polygon_plan(polygon, lines)
    origins = {"outer": "POLYGON exterior", **{f"holes[{k}]": f"POLYGON hole {k + 1}"
                                               for k in range(len(data["holes"]))},
               **{f"walls[{k}]": f"LINESTRING {k + 1}" for k in range(len(lines))}}
    return data, origins


def polygon_plan(polygon, walls=()) -> dict:
    """The tables of a floor plan (docs/plans.md: outer, holes, walls; no exit yet) of a shapely Polygon (holes:
    the obstacles) and of internal walls (LineStrings); a WKT plan's, and femcrowd.api's."""
    return {"outer": {"points": _ring(polygon.exterior.coords)},
            "holes": [{"points": _ring(ring.coords)} for ring in polygon.interiors], "exits": [],
            "walls": [{"points": [list(c[:2]) for c in line.coords]} for line in walls]}


def _ring(coords) -> list:
    """A closed ring's points without the repeated first point."""
    points = [list(map(float, c[:2])) for c in coords]
    return points[:-1] if len(points) > 1 and points[0] == points[-1] else points


def _from_dxf(file, layers, size, units):
    """The tables of the drawing's plan (in metres), the origin of each, its units and its layers' names."""
    import ezdxf
    from ezdxf import path as dxfpath

    try:
        doc = ezdxf.readfile(str(file))
    except OSError as err:
        raise InputError(file, None, None, f"cannot read the drawing: {err}") from None
    except ezdxf.DXFError as err:
        raise InputError(file, None, None, f"not a DXF drawing: {err}") from None
    unit = _unit(file, units, doc.header.get("$INSUNITS", 0))
    factor = unit[1]
    sagitta = size / 20 / factor   # arcs become chords no further than this (m) from the arc
    pieces = {"walls": [], "obstacles": [], "doors": [], "interior": []}
    circles, ignored, names, arcs = [], Counter(), set(), set()
    for entity in doc.modelspace():
        layer = entity.dxf.layer
        names.add(layer)
        kind = next((k for k in ("walls", "obstacles") if layer.lower() == layers[k].lower()), None)
        if kind is None and layer.lower().startswith(layers["interior"].lower()):
            kind = "interior"
        if kind is None and layer.lower().startswith(tuple(p.lower() for p in layers["doors"])):
            kind = "doors"
        if kind is None or entity.dxftype() not in KINDS:
            ignored[layer, entity.dxftype()] += 1
            continue
        origin = f"layer {layer!r} {entity.dxftype()} #{entity.dxf.handle}"
        if entity.dxftype() == "ARC" and kind == "walls":
            arcs.add(origin)
        if entity.dxftype() == "CIRCLE" and kind == "obstacles":
            circles.append(({"circle": {"center": (factor * np.array(entity.dxf.center)[:2]).tolist(),
                                        "radius": factor * entity.dxf.radius}}, origin))
            continue
        points = factor * np.array([(v.x, v.y) for v in dxfpath.make_path(entity).flattening(sagitta)])
        closed = entity.dxftype() == "CIRCLE" or getattr(entity, "closed", False) or getattr(entity, "is_closed",
                                                                                              False)
        pieces[kind].append((points, bool(closed), layer.lower(), origin))
    if ignored:
        log.warning("%s: ignored (not on the layers %s, %s, %s*, %s*, or not %s): %s", file, layers["walls"],
                    layers["obstacles"], "*, ".join(layers["doors"]), layers["interior"], ", ".join(KINDS),
                    "; ".join(f"layer {layer!r}: {n} {kind}" for (layer, kind), n in sorted(ignored.items())))
    span = np.ptp(np.concatenate([p for p, *_ in pieces["walls"]]), axis=0).max() if pieces["walls"] else 1.0
    tol = 1e-6 * span
    outline, partitions, free = _partitions(file, pieces["walls"], tol)
    wall_loops = _loops(file, outline, tol)
    if not wall_loops and free:
        raise InputError(file, free[0], f"({free[1][0]:g}, {free[1][1]:g})", "open outline: no closed loop on "
                         "the walls layer, and nothing joins this end (close the polyline, or join the lines and "
                         "arcs end to end)")
    if not wall_loops:
        found = "has no closed loop (closed polylines, or lines and arcs joined end to end)" if pieces["walls"] \
            else f"holds no {', '.join(KINDS)}"
        raise InputError(file, None, None, f"no outline: the walls layer {layers['walls']!r} {found}; the drawing's "
                         f"layers: {', '.join(sorted(names, key=str.lower)) or 'none'}; give the outline's layer "
                         "with --walls-layer")
    _warn_swings(file, [p for p in partitions if p[3] in arcs])
    areas = [abs(_signed_area(p)) for p, _ in wall_loops]
    outer = int(np.argmax(areas))
    holes = [loop for k, loop in enumerate(wall_loops) if k != outer] + _loops(file, pieces["obstacles"], tol)
    data = {"outer": {"points": wall_loops[outer][0].tolist()},
            "holes": [{"points": p.tolist()} for p, _ in holes] + [c for c, _ in circles], "exits": [],
            "walls": [{"points": p.tolist()} for p, *_ in partitions], "doors": []}
    origins = {"outer": wall_loops[outer][1]}
    origins.update({f"holes[{k}]": origin for k, (_, origin) in enumerate(holes + [(None, o) for _, o in circles])})
    origins.update({f"walls[{k}]": origin for k, (*_, origin) in enumerate(partitions)})
    for kind, table in (("doors", "exits"), ("interior", "doors")):   # each segment a named [[exits]], [[doors]]
        for points, _, layer, origin in pieces[kind]:
            for a, b in zip(points[:-1], points[1:]):
                origins[f"{table}[{len(data[table])}]"] = origin
                data[table].append({"name": layer, "from": a.tolist(), "to": b.tolist()})
    return data, origins, unit, sorted(names, key=str.lower)


def _warn_swings(file, arcs):
    """One warning naming the arcs among the internal walls and their ends (m): door swings drawn on the walls
    layer, each closing the doorway it spans."""
    if arcs:
        where = "; ".join(f"{origin} from ({p[0][0]:g}, {p[0][1]:g}) to ({p[-1][0]:g}, {p[-1][1]:g}) m"
                          for p, *_, origin in arcs)
        log.warning("%s: an arc on the walls layer is a wall: if it is a door swing, it closes the doorway it "
                    "spans (move it to another layer; a door between rooms is a line on the doors layer): %s",
                    file, where)


def _partitions(file, pieces, tol):
    """The pieces of the walls layer split into (outline and obstacle pieces, internal walls): an open piece
    with an end that no other open piece's end meets is an internal wall, and so on until none is left (a
    chain of internal walls comes off end by end); the rest must join end to end into loops, two pieces
    at each point. Also returns the first free end found (origin, point), or None."""
    from scipy.spatial import cKDTree

    is_closed = [p[1] or (len(p[0]) > 2 and np.linalg.norm(p[0][0] - p[0][-1]) <= tol) for p in pieces]
    closed = [p for p, c in zip(pieces, is_closed) if c]
    rest, partitions, first = [p for p, c in zip(pieces, is_closed) if not c], [], None
    while rest:
        ends = np.array([[points[0], points[-1]] for points, *_ in rest]).reshape(-1, 2)
        meeting = cKDTree(ends).query_ball_point(ends, tol, return_length=True).reshape(-1, 2) - 1
        free = (meeting == 0).any(axis=1)
        if not free.any():
            if (meeting > 1).any():
                k, end = np.argwhere(meeting > 1)[0]
                raise InputError(file, rest[k][3], f"({ends[2 * k + end][0]:g}, {ends[2 * k + end][1]:g})",
                                 f"{meeting[k, end] + 1} pieces of the walls layer end here: draw the outline as one "
                                 "closed polyline (internal walls may end anywhere on it)")
            break
        if first is None:
            k, end = np.argwhere(meeting == 0)[0]
            first = rest[k][3], ends[2 * k + end]
        partitions += [p for p, f in zip(rest, free) if f]
        rest = [p for p, f in zip(rest, free) if not f]
    return closed + rest, partitions, first


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
