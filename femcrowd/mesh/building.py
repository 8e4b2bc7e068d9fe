"""Buildings: floors at their elevations joined by straight stairs, meshed as one surface (docs/floors.md).

A building plan is a TOML file with ``[[floors]]`` (each a floor plan of docs/plans.md with a ``name`` and an
``elevation``) and ``[[stairs]]`` (a straight flight: its ``foot`` segment on the outline of the ``lower`` floor,
its ``head`` segment on the outline of the ``upper`` one). gmsh meshes every floor in its plane z = elevation and
every stair as the sloped quadrilateral foot-head; a stair shares the curve of its foot with the lower floor and
that of its head with the upper one, so the mesh is one connected surface whose nodes carry (x, y, z). Physical
surfaces: one per floor and per stair, named after them; physical lines: the exits (any floor), ``wall``, and the
interior lines ``<stair>_foot`` and ``<stair>_head`` (doors: a capacity, a flow in history.csv).
"""

from collections import defaultdict

import numpy as np

from .plan import RESERVED, PlanReader, check_plan, read_toml

#: the keys of a building plan: its own, a floor's (those of a floor plan and its name, elevation), a stair's
BUILDING_KEYS = {"": {"size", "floors", "stairs"},
                 "stairs": {"name", "lower", "upper", "foot", "head"}}


def is_building(data) -> bool:
    """A parsed TOML plan with [[floors]] is a building."""
    return "floors" in data


class FloorReader(PlanReader):
    """A PlanReader for the floor tables of a building: keys named ``floors[k].key`` in errors, and the stair ends
    checked as exits of the floor (``landings``: exit index -> the stair's key) named by their stair's key."""

    def __init__(self, file, prefix, landings):
        super().__init__(file)
        self.prefix, self.landings = prefix, landings

    def error(self, key, value, message):
        exit_key = (key or "").split(".")[0]
        if exit_key in self.landings:
            value = [value["from"], value["to"]] if isinstance(value, dict) else value
            return super().error(self.landings[exit_key], value, message.replace("the exit", "the stair's end"))
        return super().error(f"{self.prefix}.{key}" if key else self.prefix, value, message)


def read_building(file, data, require_exits=False):
    """Check a building plan (parsed TOML `data` of `file`): returns size, the floors [(name, elevation, plan)],
    plan as check_plan returns it with each stair end added as an exit named after the stair, and the stairs
    [(name, lower floor index, upper floor index, foot (2, 2), head (2, 2))]."""
    r = PlanReader(file)
    for key in data:
        if key not in BUILDING_KEYS[""]:
            raise r.error(key, data[key], f"unknown key of a building plan; known keys: "
                          f"{', '.join(sorted(BUILDING_KEYS['']))}")
    size = r.size("size", data.get("size", 0.2))
    floors_raw = data["floors"]
    if not isinstance(floors_raw, list) or not floors_raw or not all(isinstance(f, dict) for f in floors_raw):
        raise r.error("floors", floors_raw, "expected an array of tables [[floors]]")
    stairs_raw = data.get("stairs", [])
    if not isinstance(stairs_raw, list) or not all(isinstance(s, dict) for s in stairs_raw):
        raise r.error("stairs", stairs_raw, "expected an array of tables [[stairs]]")
    names = []
    for k, floor in enumerate(floors_raw):
        name, key = floor.get("name"), f"floors[{k}]"
        if not isinstance(name, str) or not name or name in RESERVED or name in names:
            raise r.error(f"{key}.name", name, "expected a name of its own, other than wall and domain")
        elevation = floor.get("elevation")
        if isinstance(elevation, bool) or not isinstance(elevation, (int, float)) or not np.isfinite(elevation):
            raise r.error(f"{key}.elevation", elevation, "expected the floor's elevation in metres, a number")
        names.append(name)
    stairs, ends = [], defaultdict(list)   # per floor: its stair ends, as exits of its plan
    for k, stair in enumerate(stairs_raw):
        key = f"stairs[{k}]"
        for field in stair:
            if field not in BUILDING_KEYS["stairs"]:
                raise r.error(f"{key}.{field}", stair[field], "unknown key; known keys: "
                              f"{', '.join(sorted(BUILDING_KEYS['stairs']))}")
        name = stair.get("name")
        if not isinstance(name, str) or not name or name in RESERVED or name in names:
            raise r.error(f"{key}.name", name, "expected a name of its own, other than wall, domain and the floors'")
        names.append(name)
        floor = {}
        for side in ("lower", "upper"):
            if stair.get(side) not in names[:len(floors_raw)]:
                raise r.error(f"{key}.{side}", stair.get(side), f"expected the name of a floor "
                              f"({', '.join(names[:len(floors_raw)])})")
            floor[side] = names.index(stair[side])
        lower, upper = floors_raw[floor["lower"]]["elevation"], floors_raw[floor["upper"]]["elevation"]
        if not upper > lower:
            raise r.error(f"{key}.upper", stair["upper"], f"is at {upper:g} m, not above the lower floor "
                          f"{stair['lower']!r} at {lower:g} m")
        segments = {}
        for side, floor_side in (("foot", "lower"), ("head", "upper")):
            segments[side] = r.points(f"{key}.{side}", stair.get(side), least=2)
            if segments[side].shape != (2, 2):
                raise r.error(f"{key}.{side}", stair.get(side), "expected a segment [[x0, y0], [x1, y1]] on the "
                              f"outline of the {floor_side} floor")
            ends[floor[floor_side]].append((f"{key}.{side}", {"name": name, "from": stair[side][0],
                                                              "to": stair[side][1]}))
        widths = [np.linalg.norm(np.diff(segments[s], axis=0)) for s in ("foot", "head")]
        if abs(widths[0] - widths[1]) > 1e-6 * max(widths):
            raise r.error(key, stair, f"a straight stair: its foot ({widths[0]:g} m) and head ({widths[1]:g} m) "
                          "must be as wide")
        stairs.append((name, floor["lower"], floor["upper"], segments["foot"], segments["head"]))
    floors = []
    for k, floor in enumerate(floors_raw):
        plan = {key: value for key, value in floor.items() if key not in ("name", "elevation")}
        plan["size"] = size
        own = plan.get("exits", [])
        if not isinstance(own, list):
            raise r.error(f"floors[{k}].exits", own, "expected an array of tables [[floors.exits]]")
        plan["exits"] = own + [table for _, table in ends[k]]
        landings = {f"exits[{len(own) + m}]": stair_key for m, (stair_key, _) in enumerate(ends[k])}
        floors.append((floor["name"], float(floor["elevation"]), check_plan(plan, FloorReader(file, f"floors[{k}]",
                                                                                          landings))))
        if floors[-1][2][5]:
            raise r.error(f"floors[{k}].doors", plan["doors"], "interior doors on a floor of a building are not "
                          "supported yet")
    exits = {e[3] for *_, plan in floors for e in plan[3]} - {s[0] for s in stairs}
    ends = {f"{s[0]}_{side}" for s in stairs for side in ("foot", "head")}
    for k, (_, _, plan) in enumerate(floors):
        for m, e in enumerate(plan[3]):
            if e[3] in ends:
                raise r.error(f"floors[{k}].exits[{m}].name", e[3], "is the name of a stair's end (the line groups "
                              "<stair>_foot and <stair>_head): name the exit otherwise")
    if require_exits and not exits:
        raise r.error("floors", names[:len(floors)], "the building has no exit: add an [[floors.exits]] segment on "
                      "the outline of a floor, or give --no-exits")
    return size, floors, stairs


def read_toml_building(file, require_exits=False):
    """The checked building of a TOML plan file (read_building), or None if the file is no building."""
    data = read_toml(file, PlanReader(file))
    return read_building(file, data, require_exits) if is_building(data) else None
