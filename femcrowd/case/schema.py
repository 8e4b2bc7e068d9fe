"""The keys of a case file: their defaults and the checks of their values (docs/case-format.md lists them).

Every key has a default, so a small scene needs a small file. A value is checked by its
kind (string, number in a range, choice, expression, ...); a bad one raises
:class:`InputError` naming the file, the key and the value.
"""

import difflib
import math
from dataclasses import dataclass

from .. import registry
from ..errors import InputError
from ..expressions import Expression, ExpressionError
from ..profiles import table_error

REQUIRED = object()
FIELDS = ("density", "pressure", "velocity")


@dataclass(frozen=True)
class Key:
    """One case key: its default, the check that turns a raw TOML value into a clean one, and what it
    means (the key's line in docs/case-format.md)."""

    default: object
    kind: str
    doc: str = ""
    choices: object = ()   # a tuple, or a function of no arguments that gives it (the models', femcrowd.registry)
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    items: dict = None   # kind "table_array": the keys of each table of the array


@dataclass(frozen=True)
class NamedTables:
    """A table of named tables, ``[section.<name>]``, each checked against ``keys`` (the populations)."""

    keys: dict
    doc: str = ""
    default = None


#: speed_law: the factor f(rho) of the desired speed (macro/speed_law.py)
SPEED_LAW_DOC = ('the desired speed is f(rho) x speed: "constant" (f = 1), "linear" (f = 1 - rho/rho_max), '
                 '"weidmann" (Weidmann 1993, rho_max in persons/m^2), "predtechenskii" (Predtechenskii, Milinskii '
                 '1978, horizontal paths, 0.1 m^2 per person, rho_max in persons/m^2; f(rho_max) > 0 without a push) '
                 'or an expression in rho (in units of rho_max, '
                 '0..1); f non-increasing in [0, 1]; f(1) = 0: the projection is never needed')
#: push: the least factor of the speed law (macro/speed_law.py)
PUSH_DOC = ("people in a jam still push at push x speed: the speed law's f never falls below it, so f(1) > 0 and "
            "the projection's pressure moves a jam towards the exits (docs/model.md); 0: a law with f(1) = 0 "
            "never pushes, and a jam where the directions meet (a door's corner) never moves")
#: the keys of one [populations.<name>] table; the velocity keys override [velocity] for this population
POPULATION = {
    "density": Key(0.0, "expr", "this population's initial density in [0, rho_max]: a number or an expression "
                   "in x, y; the populations' densities sum to at most rho_max"),
    "people": Key(None, "number", "this population's number of persons: its density (uniform if 0) is then only "
                  "a shape, scaled to hold them (discs in the micro model)", low=0, low_open=True),
    "exits": Key(None, "strlist", "for velocity type exits: the exits this population heads for (default: all)"),
    "type": Key(None, "choice", "overrides velocity.type for this population", ("exits", "field")),
    "speed": Key(None, "expr", "overrides velocity.speed for this population"),
    "speed_law": Key(None, "law", "overrides velocity.speed_law for this population"),
    "push": Key(None, "number", "overrides velocity.push for this population", low=0, high=1),
    "ux": Key(None, "expr", "overrides velocity.ux for this population"),
    "uy": Key(None, "expr", "overrides velocity.uy for this population"),
}

SCHEMA = {
    "title": Key("", "str", "a title for pictures and reports"),
    "mesh": {
        "file": Key(REQUIRED, "str", "the gmsh mesh (.msh 2.2 or 4.1), relative to case.toml"),
        "refine": Key(0, "int", "uniform refinements after loading (convergence studies)", low=0, high=8),
    },
    "boundary": {
        "exits": Key([], "strlist", "the physical line groups that are exits; every other boundary edge is a wall"),
        "open": Key({}, "schedules", "when each exit is open: a table of exit names to lists of [from, to] times "
                    "(s; to may be inf), e.g. { door = [[0, 10], [30, inf]] }; [] keeps an exit closed; "
                    "a closed exit is a wall (default: always open)"),
        "capacity": Key({}, "capacities", "the most a door lets through, persons per metre per second (density unit "
                        "x m/s): a table of door names (exits, or interior physical line groups: doors between two "
                        "rooms) to capacities, e.g. { exit = 1.9 }, or 'auto': the capacity of the door's width "
                        "(2.08 up to 1.2 m, 2.57 from 2.4 m, linear between: the means of the bottleneck experiments, "
                        "mesh/capacity.py); while a door is at capacity the crowd behind it "
                        "queues and pushes on it as on a wall (default: no cap, the free exit of the paper)"),
    },
    "model": {
        "type": Key("macro", "choice", '"macro" (a density) or "micro" (rigid discs)', ("macro", "micro")),
        "rho_max": Key(1.0, "number", "the saturation density, in the unit of the densities of the case "
                       "(e.g. 5.4 people/m^2)", low=0, low_open=True),
    },
    "velocity": {
        "type": Key("exits", "choice", '"exits": U = -speed grad d / |grad d|, d the walking distance to the '
                    'nearest exit; "field": U given by ux, uy', ("exits", "field")),
        "speed": Key(1.0, "expr", "desired speed (m/s) for type exits: a number >= 0 or an expression in x, y"),
        "speeds": Key({}, "speeds", "for type exits: the desired speed (m/s, along the slope) per physical surface "
                      "group, in place of speed there, e.g. { stair = 0.6 } for the stair of a building; a stair's "
                      "{ up = ..., down = ... }: the speed of the direction people walk there; a speed is a number or "
                      "the name of a published one, e.g. \"weidmann-up\" (docs/floors.md, \"Stair speeds\")"),
        "ux": Key(0.0, "expr", "x component of U (m/s) for type field: an expression in x, y, t"),
        "uy": Key(0.0, "expr", "y component of U (m/s) for type field: an expression in x, y, t"),
        "speed_law": Key("constant", "law", SPEED_LAW_DOC),
        "push": Key(0.0, "number", PUSH_DOC, low=0, high=1),
        "route": Key("shortest", "choice", '"shortest": U along the shortest path to the nearest open exit; '
                     '"congestion": the route sees the crowd: each place heads for the exit of least time, the '
                     'walk (Hughes 2002: a path costs 1 / f(rho) per metre, f the speed law, or 1 - rho with a '
                     'constant speed; to a door with a capacity, the walking distance) or the wait behind the '
                     'queue at a door with a capacity (docs/model.md, "Route choice"); for type exits (refused when no '
                     'population has it)',
                     ("shortest", "congestion")),
        "route_every": Key(1.0, "number", 'with route = "congestion": the routes are re-solved every route_every '
                           "seconds of simulated time and at every door change", low=0, low_open=True),
        "walls": Key("paper", "choice", 'for type exits: "paper": the direction of the P1 gradient of the distance '
                     'as it is (in a cell at a wall it may point into the wall, whose facet carries nothing); "slip": '
                     'no component into a wall (U . n <= 0 there, as in the continuum) and every cell that can reach '
                     'an exit has a path of upwind flows to one (docs/model.md, "Walls")', ("paper", "slip")),
        "clearance": Key(0.0, "number", "for type exits: r (m), the clearance people keep from walls and door posts: "
                         "the walking distance costs 4 times more within r of a wall, so that the shortest paths "
                         "round a door post on an arc of radius r instead of meeting at the post (e.g. 0.25, half a "
                         'shoulder width); 0: the distance of the paper (docs/model.md, "A clearance at the walls")',
                         low=0),
    },
    "populations": NamedTables(POPULATION, "several populations, one table [populations.<name>] each (name: letters, "
                          "digits, _ and -), sharing one constraint and one pressure; without it the crowd of "
                          "[initial] is one population"),
    "initial": {
        "density": Key(0.0, "expr", "initial density in [0, rho_max]: a number or an expression in x, y"),
        "regions": Key({}, "regions", "initial density per physical surface group, e.g. { crowd = 0.9 }"),
        "people": Key(None, "number", "the number of persons at t = 0: the initial density (uniform if it is 0 "
                      "everywhere) is then only a shape, scaled to hold them; refused if they cannot fit under "
                      "rho_max (persons/m^2); discs in the micro model (instead of micro.count)", low=0,
                      low_open=True),
    },
    "time": {
        "end": Key(10.0, "number", "end time (s)", low=0, low_open=True),
        "cfl": Key(0.5, "number", "time step as a fraction of the CFL-1 step of the upwind transport (with a "
                   "speed law: of the LWR transport), in "
                   "(0, 1] for upwind, (0, 0.5] for muscl and compressive, (0, 100] for implicit and "
                   "implicit-godunov"),
        "cfl_quantile": Key(0.0, "number", "the cell whose CFL-1 step time.cfl multiplies, as a quantile of the "
                            "cells' CFL-1 steps: 0, the smallest cell (what the explicit transports need); with "
                            "scheme.transport = implicit or implicit-godunov a larger one, e.g. 0.5 (the median "
                            "cell), sets the step by the crowd's motion, not by the smallest triangle "
                            "(docs/model.md, \"Steps by accuracy\")", low=0, high=1),
        "dt": Key(None, "number", "a fixed time step (s) instead of cfl", low=0, low_open=True),
        "stop_when_empty": Key(True, "bool", "stop once the crowd has left (scenes with exits)"),
        "empty_fraction": Key(1e-4, "number", "the crowd has left when less than this fraction of it is inside "
                              "(at most 0.1: the evacuation time is that of 90 % of the crowd out, or more)",
                              low=0, high=0.1, low_open=True),
    },
    "output": {
        "dir": Key("output", "str", "output directory, relative to case.toml (--out on the command line "
                   "is relative to the current directory)"),
        "every": Key(0.5, "number", "time between frames (s)", low=0, low_open=True),
        "fields": Key(list(FIELDS), "fields", "the cell fields written in the frames"),
        "trajectory_rate": Key(10.0, "number", "micro runs: frames per second of trajectories.txt (disc "
                               "trajectories in PedPy's Juelich text format, with walkable_area.wkt)",
                               low=0, low_open=True),
    },
    "projection": {
        "direct_max": Key(1_000_000, "int", "largest saturated set solved by sparse Cholesky (larger: AMG + CG)",
                          low=0),
        "tol": Key(1e-12, "number", "density tolerance of iterative solves: rho <= 1 + tol", low=0, high=1e-6,
                   low_open=True),
    },
    "micro": {
        "radius": Key(0.2, "radius", "disc radius (m), or [min, max] for a polydisperse crowd"),
        "count": Key(None, "int", "number of discs (default: initial.people, else from the initial density at "
                     "the hexagonal packing density)", low=1),
        "seed": Key(1, "int", "seed of the disc sampling"),
        "positions": Key(None, "str", "a CSV of discs (columns x, y, r) instead of sampling, relative to case.toml"),
        "method": Key("exact", "choice", "the projection of the velocities: exact (exact to round-off, in jams "
                      "to a certified relative objective gap of 1e-7 with no overlap), or Uzawa's iteration",
                      ("exact", "uzawa")),
        "strategy": Key("push", "choice", "what a disc does behind slower visible neighbours (Maury et al. 2011): "
                        "push on, decelerate to their mean speed, or bypass them", registry.strategies),
        "view_distance": Key(1.0, "number", "how far a disc sees (m): the neighbours of the strategies and the "
                             "density of the speed law", low=0, low_open=True),
        "view_angle": Key(45.0, "number", "half angle of view (degrees) of the strategies and the speed law",
                          low=0, high=90, low_open=True),
        "walls": Key("paper", "choice", 'the direction of the discs at walls: "paper", that of the density model\'s '
                     'walking distance (a disc can stay at a wall\'s end it turns around); "clearance", the walking '
                     'distance of disc centres kept a radius from the walls (docs/micro.md, "Walls and corners")',
                     ("paper", "clearance")),
        "fluctuation": Key(0.0, "number", "the standard deviation (m/s, per component) of a random perturbation of "
                           "each disc's desired velocity, an Ornstein-Uhlenbeck process of correlation time 0.5 s "
                           "seeded from micro.seed, which breaks the arches at narrow doors (2.5 lets pushing discs "
                           "through a 0.5 m door: docs/micro.md); 0: the discs of Maury and Venel", low=0),
    },
    "scheme": {
        "transport": Key("upwind", "choice", "the prediction: order-0 upwind; limited linear reconstruction with "
                         "SSP-RK2 (muscl; with a speed law Godunov's flux between the reconstructed values, always "
                         "followed by the projection: docs/model.md, \"muscl with a speed law\") or one Euler stage "
                         "(compressive, no speed law); backward-Euler upwind, positive at any "
                         "time step (implicit; with a speed law linearly implicit, the speed of the step's start); "
                         "the explicit fluxes (upwind; with a speed law the LWR fluxes, Godunov's for a unimodal "
                         "flow) with their rates at the step's start, implicit only in the cells whose CFL-1 step the "
                         "step exceeds: the explicit step within it, positive at any step (implicit-godunov; "
                         "docs/model.md, \"Steps by accuracy\")",
                         registry.transports),
    },
    "exact": Key(None, "exact", "the exact solution of the case, the reference of femcrowd convergence: "
                 "{ name = ..., and its parameters }, e.g. { name = \"saturated-evacuation\", k = 1.0, s0 = 1.0 }"),
    "sources": Key([], "table_array", "people arriving through a boundary group that is not an exit ([[sources]])",
                   items={
                       "boundary": Key(REQUIRED, "str", "the physical line group they enter through"),
                       "flow": Key(None, "profile", "persons per metre of the group per second (density unit "
                                   "x m/s): a number, an expression in t, or a table [[t, flow], ...] (linear between "
                                   "its points, 0 outside them); what cannot enter waits outside (history column "
                                   "queued); exactly one of flow, rate, people"),
                       "rate": Key(None, "profile", "persons per second through the whole group, as flow is per "
                                   "metre: a number, an expression in t or a table [[t, rate], ...] (a timetable); "
                                   "discs per second in the micro model"),
                       "people": Key(None, "number", "persons arriving at an even rate over [start, end] (discs "
                                     "in the micro model)", low=0, low_open=True),
                       "start": Key(0.0, "number", "when they start arriving (s)", low=0),
                       "end": Key(None, "number", "when they stop arriving (s; default: time.end)", low=0),
                       "population": Key(None, "str", "the population they join (default: the first)"),
                   }),
    "measure": {
        "lines": Key([], "table_array", "counting lines ([[measure.lines]]): flow and cumulative count from left "
                     "to right of from -> to, in measurements.csv",
                     items={
                         "name": Key(REQUIRED, "name", "the line's name (columns <name>_flow, <name>_count; discs: "
                                     "<name>_passed)"),
                         "from": Key(REQUIRED, "point", "first end [x, y] (m)"),
                         "to": Key(REQUIRED, "point", "second end [x, y] (m)"),
                     }),
        "areas": Key([], "table_array", "measurement areas ([[measure.areas]]): mean density, mean speed and max "
                     "pressure in a polygon, in measurements.csv",
                     items={
                         "name": Key(REQUIRED, "name", "the area's name (columns <name>_density, <name>_speed, "
                                     "<name>_pressure)"),
                         "polygon": Key(REQUIRED, "polygon", "its corners [[x, y], ...] (m), a simple polygon"),
                     }),
    },
    "convergence": {
        "meshes": Key([], "strlist", "mesh files of a refinement series, instead of mesh.refine"),
        "reference": Key(None, "str", "a CSV of published error / run-time figures (method, metric, seconds, "
                         "error) drawn on the plots"),
    },
}


def is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class Refused(ValueError):
    """A value a checker refuses: the message, and the sub-key (and its value) it is about, None for the key."""

    def __init__(self, message, sub=None, value=None):
        super().__init__(message)
        self.sub, self.value = sub, value


def check_value(spec: Key, value, file, key: str):
    """The clean value of a raw TOML value for the key `key` (checked by the CHECKERS of its kind), or InputError
    naming the file, the key (or its sub-key) and the value."""
    try:
        return CHECKERS[spec.kind](spec, value)
    except Refused as refused:
        if refused.sub is None:
            raise InputError(file, key, value, str(refused)) from None
        raise InputError(file, f"{key}.{refused.sub}", refused.value, str(refused)) from None


def _string(spec, value):
    if not isinstance(value, str):
        raise Refused("expected a string")
    return value


def _boolean(spec, value):
    if not isinstance(value, bool):
        raise Refused("expected true or false")
    return value


def _choice(spec, value):
    choices = spec.choices() if callable(spec.choices) else spec.choices
    if value not in choices:
        raise Refused(f"expected one of {', '.join(map(repr, choices))}")
    return value


def _number(spec, value):
    integer = spec.kind == "int"
    if not is_number(value) or (integer and not isinstance(value, int)):
        raise Refused("expected an integer" if integer else "expected a number")
    if not math.isfinite(value):
        raise Refused("expected a finite number")
    below = value <= spec.low if spec.low_open else value < spec.low
    if below or value > spec.high:
        raise Refused(f"must be in {'(' if spec.low_open else '['}{spec.low:g}, {spec.high:g}"
                      f"{']' if math.isfinite(spec.high) else ')'}")   # inf is refused above
    return value


def _expression(spec, value):
    """A number, or an expression in x, y, t (femcrowd.expressions: parsed safely, never eval)."""
    if is_number(value):
        if not math.isfinite(value):
            raise Refused("expected a finite number")
        return value
    if not isinstance(value, str):
        raise Refused("expected a number or an expression string")
    try:
        Expression(value)
    except ExpressionError as err:
        raise Refused(str(err)) from None
    return value


def _strings(spec, value):
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise Refused("expected a list of strings")
    return value


def _fields(spec, value):
    bad = [v for v in _strings(spec, value) if v not in FIELDS]
    if bad:
        raise Refused(f"unknown field {bad[0]!r} (fields: {', '.join(FIELDS)})")
    return value


def _regions(spec, value):
    if not isinstance(value, dict) or not all(is_number(v) for v in value.values()):
        raise Refused("expected a table of surface-group names to numbers")
    return value


def _speeds(spec, value):
    """velocity.speeds: per surface group a speed, or a stair's { up = speed, down = speed }; a speed a number >= 0
    (m/s) or the name of a published one (registry.stair_speeds)."""
    if not isinstance(value, dict):
        raise Refused("expected a table of surface-group names to speeds")
    names = registry.stair_speeds()

    def speed(v, sub):
        if not (isinstance(v, str) and v in names or is_number(v) and math.isfinite(v) and v >= 0):
            raise Refused(f"expected a speed >= 0 (m/s) or one of {', '.join(map(repr, names))}", sub, v)

    for name, v in value.items():
        if not isinstance(v, dict):
            speed(v, name)
        elif set(v) != {"up", "down"}:
            raise Refused("expected a speed or a stair's { up = speed, down = speed }", name, v)
        else:
            for direction in ("up", "down"):
                speed(v[direction], f"{name}.{direction}")
    return value


def _law(spec, value):
    """A speed law: one of the models' names, or an expression in rho (femcrowd.registry checks it)."""
    if not isinstance(value, str):
        raise Refused(f"expected one of {', '.join(map(repr, registry.speed_laws()))} or an expression in rho")
    error = registry.speed_law_error(value)
    if error:
        raise Refused(error)
    return value


def _exact(spec, value) -> dict:
    """[exact]: the name of an exact solution and numbers for its parameters (which of them a solution takes is
    checked when it is built, studies/measures.py)."""
    if not isinstance(value, dict):
        raise Refused("expected a table { name = ..., and parameters }")
    solutions = registry.exact_solutions()
    parameters = sorted({p for names in solutions.values() for p in names})
    for name, item in value.items():
        if name == "name":
            if item is not None and item not in solutions:
                raise Refused(f"expected one of {', '.join(map(repr, solutions))}", name, item)
        elif name not in parameters:
            close = difflib.get_close_matches(name, parameters, n=1)
            raise Refused("unknown key" + (f" (did you mean {close[0]!r}?)" if close
                                           else f" (parameters: {', '.join(parameters)})"), name, item)
        elif not is_number(item) or not math.isfinite(item):
            raise Refused("expected a finite number", name, item)
    return {"name": None, **value}   # a table without a name is refused when the solution is built


def _radius(spec, value):
    ok = is_number(value) and value > 0 or (
        isinstance(value, list) and len(value) == 2 and all(is_number(v) for v in value) and 0 < value[0] <= value[1])
    if not ok:
        raise Refused("expected a positive number or [min, max]")
    return value


def _name(spec, value):
    if not isinstance(value, str) or not value.replace("_", "").replace("-", "").isalnum():
        raise Refused("expected a name of letters, digits, _ and -")
    return value


def _point_value(spec, value):
    if not _point(value):
        raise Refused("expected a point [x, y]")
    return [float(v) for v in value]


def _polygon(spec, value):
    if not isinstance(value, list) or len(value) < 3 or not all(_point(p) for p in value):
        raise Refused("expected a polygon [[x, y], ...] of at least 3 points")
    return [[float(v) for v in p] for p in value]


def _capacities(spec, value):
    if not isinstance(value, dict):
        raise Refused("expected a table of door names to capacities (persons per metre per second)")
    for name, c in value.items():
        if c != "auto" and (not is_number(c) or not math.isfinite(c) or c <= 0):
            raise Refused('expected a capacity > 0 (persons per metre per second) or "auto"', name, c)
    return {name: c if c == "auto" else float(c) for name, c in value.items()}


def _schedules(spec, value):
    if not isinstance(value, dict):
        raise Refused("expected a table of exit names to lists of [from, to] times")
    for name, spans in value.items():
        ok = isinstance(spans, list) and all(
            isinstance(s, list) and len(s) == 2 and all(is_number(v) and not math.isnan(v) for v in s)
            and 0 <= s[0] < s[1] and math.isfinite(s[0]) for s in spans)
        if not ok:
            raise Refused("expected a list of [from, to] pairs of times with 0 <= from < to (to may be inf)",
                          name, spans)
    return {name: [[float(a), float(b)] for a, b in spans] for name, spans in value.items()}


def _profile(spec, value):
    """A flow over time (femcrowd.profiles): a number >= 0, an expression in t, or a table of [t, value] pairs."""
    if isinstance(value, list):
        error = table_error(value)
        if error:
            raise Refused(error)
        return value
    if isinstance(value, str):
        try:
            Expression(value, ("t",))
        except ExpressionError as err:
            raise Refused(str(err)) from None
        return value
    if not is_number(value) or not math.isfinite(value):
        raise Refused("expected a number, an expression in t or a table [[t, value], ...]")
    if value < 0:
        raise Refused("must be in [0, inf]: a flow is >= 0")
    return value


def _tables(spec, value):
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise Refused("expected an array of tables")
    return value   # each table is resolved against spec.items by case.loading


#: the check of each kind of key: checker(spec, raw value) -> clean value, or Refused
CHECKERS = {"str": _string, "bool": _boolean, "choice": _choice, "number": _number, "int": _number,
            "expr": _expression, "strlist": _strings, "fields": _fields, "regions": _regions, "speeds": _speeds,
            "law": _law,
            "exact": _exact, "radius": _radius, "name": _name, "point": _point_value, "polygon": _polygon,
            "capacities": _capacities, "schedules": _schedules, "table_array": _tables,
            "profile": _profile}


def _point(value) -> bool:
    return isinstance(value, list) and len(value) == 2 and all(is_number(v) and math.isfinite(v) for v in value)
