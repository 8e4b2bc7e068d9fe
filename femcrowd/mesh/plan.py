"""Floor plans: the tables of a plan, read and checked.

A floor plan is a TOML file or the same tables made from a CAD drawing (:mod:`femcrowd.mesh.cad`); the
format, its units and its rules are in docs/plans.md. :func:`check_plan` checks either, naming the file and
the key of any error, and returns what :func:`femcrowd.mesh.floorplan.build_mesh` meshes: the outer polygon
and its holes (obstacles), the internal walls ``[[walls]]`` cut out of them (mesh/partitions.py), the named
exits on the boundary (a name starting with "entrance" is an entrance: :func:`is_entrance`) and the
named interior lines ``[[doors]]``. All lengths are in metres; a plan smaller than 1 m or larger than 10 km
across is refused as a mistake of units.
"""

import difflib
import pathlib
import tomllib

import numpy as np

from ..errors import InputError
from .partitions import DEFAULT_THICKNESS, cut_partitions

KEYS = {
    "": {"size", "outer", "exits", "holes", "doors", "walls"},
    "outer": {"points"},
    "walls": {"points", "thickness"},
    "exits": {"name", "from", "to", "size"},
    "doors": {"name", "from", "to"},
    "holes": {"circle", "points"},
    "circle": {"center", "radius"},
}
RESERVED = {"wall", "domain"}
#: the extent (m) of a plan that can be a building, from a room to a campus; outside it, a mistake of units
PLAUSIBLE = (1.0, 1e4)
#: the most triangles a plan may ask for (10x the largest benchmark): more is a mistake of units or of size
MAX_TRIANGLES = 1e7


def is_entrance(name) -> bool:
    """A boundary group named entrance* is where people arrive (a source), not an exit."""
    return name.lower().startswith("entrance")

# Geometry checks are plain numpy segment tests with the plan's length tolerance tol (points closer than tol
# meet), vectorised over all edges; shapely's predicates are exact and have no such tolerance.


def _orient(a, b, c, tol):
    """Sign of the turn a -> b -> c; 0 when c lies within tol of the line ab."""
    d, e = b - a, c - a
    o = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    return np.sign(o) * (np.abs(o) > tol * np.linalg.norm(d, axis=-1))


def _meet(a0, a1, b0, b1, tol):
    """Matrix (len(a0), len(b0)): do the closed segments a0a1 and b0b1 meet?"""
    a0, a1, b0, b1 = a0[:, None], a1[:, None], b0[None], b1[None]
    box = np.all((np.minimum(a0, a1) <= np.maximum(b0, b1) + tol)
                 & (np.minimum(b0, b1) <= np.maximum(a0, a1) + tol), axis=-1)
    return (box & (_orient(a0, a1, b0, tol) * _orient(a0, a1, b1, tol) <= 0)
            & (_orient(b0, b1, a0, tol) * _orient(b0, b1, a1, tol) <= 0))


def polygon_edges(p):
    """The edges of the closed polygon p (n, 2): their starts and ends, (n, 2) each."""
    return p, np.roll(p, -1, axis=0)


def _inside(q, p):
    """Are the points q (m, 2) inside the polygon p (ray casting)?"""
    a, b = polygon_edges(p)
    qx, qy = q[:, None, 0], q[:, None, 1]
    straddle = (a[:, 1] > qy) != (b[:, 1] > qy)
    right = ((b[:, 0] - a[:, 0]) * (qy - a[:, 1]) - (qx - a[:, 0]) * (b[:, 1] - a[:, 1])) * (b[:, 1] - a[:, 1]) > 0
    return np.count_nonzero(straddle & right, axis=1) % 2 == 1


def _distance(q, p):
    """Distance from the points q (m, 2) to the boundary of the polygon p."""
    a, b = polygon_edges(p)
    d = b - a
    t = np.clip(((q[:, None] - a) * d).sum(-1) / (d * d).sum(-1), 0, 1)
    return np.linalg.norm(q[:, None] - a - t[..., None] * d, axis=-1).min(axis=1)


def _holes_meet(h, g, tol):
    """Do two holes, ("circle", centre, radius) or ("polygon", points), meet?"""
    if h[0] == g[0] == "circle":
        return np.linalg.norm(h[1] - g[1]) <= h[2] + g[2] + tol
    if h[0] == "polygon" and g[0] == "circle":
        h, g = g, h
    if h[0] == "circle":
        return bool(_inside(h[1][None], g[1])[0] or _distance(h[1][None], g[1])[0] <= h[2] + tol)
    return bool(_meet(*polygon_edges(h[1]), *polygon_edges(g[1]), tol).any()
                or _inside(h[1][:1], g[1])[0] or _inside(g[1][:1], h[1])[0])


class PlanReader:
    """Typed access to the parsed TOML, raising InputError that names file and key.

    require_exits: a plan without an exit is an error (``femcrowd mesh`` without ``--no-exits``), its message
    ending with ``no_exits_hint``; ``units`` names the plan's length unit in the error of an implausible size.
    """

    units = "m"
    no_exits_hint = "add an [[exits]] segment on the outline, or give --no-exits for a plan nobody leaves"

    def __init__(self, file, require_exits=False):
        self.file, self.require_exits = file, require_exits

    def units_hint(self, extent):
        """What to do about a plan of an implausible extent (m)."""
        return "; a TOML plan's lengths are in metres"

    def error(self, key, value, message):
        return InputError(self.file, key, value, message)

    def table(self, key, value, kind):
        if not isinstance(value, dict):
            raise self.error(key, value, "expected a table")
        for k in value:
            if k not in KEYS[kind]:
                close = difflib.get_close_matches(k, KEYS[kind], n=1)
                hint = f"; did you mean {close[0]!r}?" if close else f"; known keys: {', '.join(sorted(KEYS[kind]))}"
                raise self.error(f"{key}.{k}" if key else k, value[k], "unknown key" + hint)
        return value

    def tables(self, key, value, kind):
        if not isinstance(value, list):
            raise self.error(key, value, f"expected an array of tables [[{key}]]")
        return [self.table(f"{key}[{k}]", v, kind) for k, v in enumerate(value)]

    def size(self, key, value):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
            raise self.error(key, value, "expected a positive number")
        return float(value)

    def points(self, key, value, polygon=True, least=3):
        """A list of at least `least` points (n, 2), or one point [x, y] (polygon=False)."""
        try:
            a = np.array(value, dtype=float)
        except (TypeError, ValueError):
            a = np.zeros(0)
        ok = a.ndim == 2 and a.shape[1] == 2 if polygon else a.shape == (2,)
        if not ok or not np.isfinite(a).all():
            raise self.error(key, value, "expected a list of [x, y] points" if polygon else "expected a point [x, y]")
        if polygon and len(a) < least:
            raise self.error(key, value, "a polygon needs at least 3 points" if least == 3 else
                             f"a line needs at least {least} points")
        return a

    def polygon(self, key, value, tol):
        """A simple polygon (no repeated points, no crossing or folded edges), made counter-clockwise."""
        p = self.points(key, value)
        a, b = polygon_edges(p)
        n = len(p)
        i, j = np.indices((n, n))
        adjacent = (abs(i - j) <= 1) | (abs(i - j) == n - 1)
        prev = np.roll(p, 1, axis=0)
        fold = (_orient(prev, p, b, tol) == 0) & (((prev - p) * (b - p)).sum(-1) > 0)
        if (np.linalg.norm(b - a, axis=1) <= tol).any():
            raise self.error(key, value, "repeated consecutive point")
        if (_meet(a, b, a, b, tol) & ~adjacent).any() or fold.any():
            raise self.error(key, value, "the polygon intersects itself")
        return p if (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum() > 0 else p[::-1]


def read_toml_plan(file, require_exits=False):
    """Parse and check a floor plan.

    Returns size, the polygon loops (outer first, then polygon holes), the
    circle holes, the exits (edge index into the concatenated loops, t0, t1,
    name, local size or None, length), the length tolerance and the doors
    (from, to, name).
    """
    r = PlanReader(file, require_exits)
    return check_plan(read_toml(file, r), r)


def read_toml(file, r):
    """The parsed TOML of a plan file; a syntax error or an unreadable file named by the reader r."""
    try:
        return tomllib.loads(pathlib.Path(file).read_text())
    except tomllib.TOMLDecodeError as e:
        raise r.error(None, None, f"TOML syntax error: {e}") from None
    except OSError as e:
        raise r.error(None, None, f"cannot read the geometry file: {e.strerror}") from None


def check_plan(data, r):
    """Check a floor plan given as the parsed TOML (or the same tables made from a CAD drawing, mesh/cad.py)
    with the reader r that names file and keys in errors; returns what read_toml_plan returns."""
    r.table("", data, "")
    size = r.size("size", data.get("size", 0.2))
    if "outer" not in data:
        raise r.error("outer", None, "missing: the outer boundary polygon [outer] points = [[x, y], ...]")
    points = r.table("outer", data["outer"], "outer").get("points")
    extent = np.ptp(r.points("outer.points", points), axis=0)
    if not PLAUSIBLE[0] <= extent.max() <= PLAUSIBLE[1]:
        raise r.error("units", r.units, f"the plan is {extent[0]:.3g} m x {extent[1]:.3g} m, not the size of a "
                      "building (1 m to 10 km across)" + r.units_hint(extent.max()))
    tol = 1e-6 * extent.max()
    outer = r.polygon("outer.points", points, tol)
    a, b = polygon_edges(outer)
    triangles = 2.3 * 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum() / size ** 2   # equilateral, side size
    if triangles > MAX_TRIANGLES:
        raise r.error("units", r.units, f"the plan is {extent[0]:.3g} m x {extent[1]:.3g} m: at a cell size of "
                      f"{size:g} m it would take about {triangles:.1g} triangles" + r.units_hint(extent.max())
                      + ", or a larger cell size")

    holes = []
    for k, hole in enumerate(r.tables("holes", data.get("holes", []), "holes")):
        key = f"holes[{k}]"
        if ("circle" in hole) == ("points" in hole):
            raise r.error(key, hole, "a hole needs exactly one of 'circle' or 'points'")
        if "points" in hole:
            h = ("polygon", r.polygon(f"{key}.points", hole["points"], tol))
            inside = not _meet(*polygon_edges(h[1]), *polygon_edges(outer), tol).any() and _inside(h[1][:1], outer)[0]
        else:
            c = r.table(f"{key}.circle", hole["circle"], "circle")
            h = ("circle", r.points(f"{key}.circle.center", c.get("center"), polygon=False),
                 r.size(f"{key}.circle.radius", c.get("radius")))
            inside = _inside(h[1][None], outer)[0] and _distance(h[1][None], outer)[0] > h[2] + tol
        if not inside:
            raise r.error(key, hole, "the hole must lie strictly inside the outer boundary")
        for m, g in enumerate(holes):
            if _holes_meet(h, g, tol):
                raise r.error(key, hole, f"the hole touches or overlaps holes[{m}]")
        holes.append(h)

    circles = [h for h in holes if h[0] == "circle"]
    loops = [outer] + [h[1] for h in holes if h[0] == "polygon"]
    walls = [(f"walls[{k}]", r.points(f"walls[{k}].points", w.get("points"), least=2),
              r.size(f"walls[{k}].thickness", w.get("thickness", DEFAULT_THICKNESS)))
             for k, w in enumerate(r.tables("walls", data.get("walls", []), "walls"))]
    for key, points, _ in walls:
        if (np.linalg.norm(np.diff(points, axis=0), axis=1) <= tol).any():
            raise r.error(f"{key}.points", points.tolist(), "repeated consecutive point")
    if walls:
        outline, polygons = cut_partitions(loops[0], loops[1:], circles, walls, tol, r.error)
        loops = [r.polygon("outer.points", outline, tol)] + [r.polygon("walls", p, tol) for p in polygons]

    # exits: each on one straight edge of the outer polygon or of a polygon hole
    a = np.concatenate([polygon_edges(p)[0] for p in loops])
    d = np.concatenate([polygon_edges(p)[1] - polygon_edges(p)[0] for p in loops])
    exits = []
    for k, ex in enumerate(r.tables("exits", data.get("exits", []), "exits")):
        key = f"exits[{k}]"
        name = ex.get("name")
        if not isinstance(name, str) or not name or name in RESERVED:
            raise r.error(f"{key}.name", name, f"expected a non-empty name other than {' and '.join(sorted(RESERVED))}")
        ends = np.array([r.points(f"{key}.{s}", ex.get(s), polygon=False) for s in ("from", "to")])
        t = ((ends[:, None] - a) * d).sum(-1) / (d * d).sum(-1)  # (2, edges)
        off = np.linalg.norm(ends[:, None] - a - t[..., None] * d, axis=-1)
        slack = tol / np.linalg.norm(d, axis=1)
        on = np.flatnonzero(np.all((off <= tol) & (t >= -slack) & (t <= 1 + slack), axis=0))
        if not len(on):
            raise r.error(key, ex, "the exit must lie on one straight edge of the outer polygon or of a polygon hole")
        e = on[0]
        t0, t1 = np.sort(np.clip(t[:, e], 0, 1))
        if (t1 - t0) * np.linalg.norm(d[e]) <= tol:
            raise r.error(key, ex, "the exit has zero length")
        for m, (f, s0, s1, *_) in enumerate(exits):
            if f == e and min(t1, s1) - max(t0, s0) > slack[e]:
                raise r.error(key, ex, f"the exit overlaps exits[{m}]")
        h = r.size(f"{key}.size", ex["size"]) if "size" in ex else None
        exits.append((e, t0, t1, name, h, (t1 - t0) * np.linalg.norm(d[e])))
    if r.require_exits and all(is_entrance(e[3]) for e in exits):
        raise r.error("exits", sorted({e[3] for e in exits}), "the plan has no exit: " + r.no_exits_hint)
    return size, loops, circles, exits, tol, _doors(data, r, loops, circles, {e[3] for e in exits}, tol)


def _doors(data, r, loops, circles, exit_names, tol):
    """The [[doors]]: straight segments inside the domain (ends on the boundary or inside), as (from, to, name)."""
    a = np.concatenate([polygon_edges(p)[0] for p in loops])
    b = np.concatenate([polygon_edges(p)[1] for p in loops])
    doors = []
    for k, door in enumerate(r.tables("doors", data.get("doors", []), "doors")):
        key = f"doors[{k}]"
        name = door.get("name")
        if not isinstance(name, str) or not name or name in RESERVED or name in exit_names:
            raise r.error(f"{key}.name", name, "expected a non-empty name other than wall, domain and the exits'")
        ends = np.array([r.points(f"{key}.{s}", door.get(s), polygon=False) for s in ("from", "to")])
        if np.linalg.norm(ends[1] - ends[0]) <= tol:
            raise r.error(key, door, "the door has zero length")
        # inside: no boundary edge crossed between the ends, the points of the segment inside the outer polygon
        # and outside every hole
        inner = ends[0] + np.array([[1e-3], [0.5], [1 - 1e-3]]) * (ends[1] - ends[0])
        crossing = _meet(inner[:1], inner[2:], a, b, tol).any()
        inside = _inside(inner, loops[0]).all() and not any(_inside(inner, h).any() for h in loops[1:])
        direction = ends[1] - ends[0]
        near = [np.clip((c - ends[0]) @ direction / (direction @ direction), 0, 1) for _, c, _ in circles]
        hits = any(np.linalg.norm(c - ends[0] - t * direction) <= radius + tol
                   for (_, c, radius), t in zip(circles, near))
        if crossing or not inside or hits:
            raise r.error(key, door, "the door must lie inside the domain (its ends on the boundary or inside)")
        doors.append((ends[0], ends[1], name))
    return doors
