"""``femcrowd new``: a commented case.toml for a mesh: the keys a new case sets and the commented-out options
beside them; exits = the mesh's boundary groups not named wall* nor entrance*; a group named entrance*
(mesh/plan.py is_entrance) becomes a ``[[sources]]`` entry; a mesh without an exit gets the desired velocity
U = 0 to edit (not a direction made up for it). Every other key is in the case-format documentation.

Two models (MODELS): "recommended", the settings of docs/validation.md (femcrowd/studies/recommended.py:
rho_max 5.4 persons/m^2, Predtechenskii and Milinskii's law at its free speed 1.67 m/s, the walls' slip, the
capacity of its width on every exit and interior line group, by name); "paper", the model of Maury et al. (2010)
at the SCHEMA's defaults (rho_max 1, constant speed, free exits), the capacities offered as a comment."""

import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..files import make_directory, write_text
from ..mesh.capacity import width_capacity
from ..studies.recommended import DOOR_CAPACITY, FLUCTUATION, FREE_SPEED, LAW, PUSH, STEP, WALLS, WEIDMANN_SPEED
from .loading import toml_value
from .schema import SCHEMA

#: the models `femcrowd new --model` writes: the recommended settings (the default) or the paper's model
MODELS = ("recommended", "paper")
#: the initial density written (persons/m^2)
DENSITY = 2.0


def _default(section, key):
    return toml_value(SCHEMA[section][key].default)


def wall_like(name):
    return name.lower().startswith("wall")


def new_case_file(case_dir) -> Path:
    """CASE_DIR/case.toml, which must not exist yet: ``femcrowd new`` never overwrites a case."""
    file = Path(case_dir) / "case.toml"
    if file.exists():
        raise InputError(file, None, None, "already exists: femcrowd new never overwrites a case "
                         "(choose another directory, or edit this file)")
    return file


def door_groups(domain):
    """(exits, entrances, interior lines) of a mesh: its boundary groups not named wall* nor entrance*, those
    named entrance* (mesh/plan.py is_entrance), and its groups of interior facets."""
    from ..mesh.plan import is_entrance

    groups = domain.statistics()["boundary_groups"]
    inside = [name for name, facets in domain.groups.items() if len(facets) and domain.interior[facets].all()]
    entrances = [name for name in groups if is_entrance(name) and name not in inside]
    exits = [name for name in groups if not wall_like(name) and name not in inside and name not in entrances]
    return exits, entrances, inside


def write_new_case(file: Path, mesh_file, domain, model: str = "recommended") -> None:
    """Write the case file ``file`` for the mesh ``mesh_file`` (its Domain ``domain``), with the settings of
    ``model`` (one of MODELS)."""
    case_dir, mesh_file = file.parent, Path(mesh_file)
    lines = _case_lines(case_dir, mesh_file, domain)
    if model == "recommended":
        lines = _recommended(lines, domain)
    text = "".join((f"{line[0]:<30}  # {line[1]}" if isinstance(line, tuple) else line) + "\n" for line in lines)
    write_text(make_directory(case_dir) / file.name, text, sync=True)


def _case_lines(case_dir, mesh_file, domain) -> list:
    """The lines of the case file: text, or (text, comment) pairs."""
    groups = domain.statistics()["boundary_groups"]
    exits, entrances, inside = door_groups(domain)
    surfaces = [name for name in (domain.mesh.subdomains or {}) if not name.startswith("gmsh:")]
    (x0, y0), (x1, y1) = domain.points.min(axis=0), domain.points.max(axis=0)
    # about four walks across the floor at 1 m/s; the run stops earlier once everybody has left
    end = 10.0 * math.ceil(0.4 * math.hypot(x1 - x0, y1 - y0))
    relative = Path(os.path.relpath(mesh_file.resolve(), case_dir.resolve())).as_posix()
    group_list = ", ".join(f"{n} ({groups[n]:.3g} m)" for n in groups) or "none"
    if exits:
        velocity = [('type = "exits"', "U = -speed grad d / |grad d|, d = walking distance to the nearest exit"),
                    (f'speed = {_default("velocity", "speed")}', "m/s: number or expression in x, y"),
                    *_stair_speeds(domain),
                    ('# speed_law = "weidmann"', "slower in a dense crowd (rho_max in persons/m^2)"),
                    ("# push = 0.2", "with a speed law: a jam still pushes at push x speed"),
                    ('# route = "congestion"', "each place heads for the exit of least time: walk or queue"),
                    ('# type = "field"', "or U given by expressions in x, y, t:"), '# ux = "-1"', '# uy = "0"']
    else:
        velocity = [('type = "field"', "the mesh has no exit: U given by expressions in x, y, t"),
                    ('ux = "0"', "people stand still until you give U, e.g. ux = \"1\""), 'uy = "0"']
    sources = [line for name in entrances for line in (
        "", ("[[sources]]", "people arriving through an entrance"),
        (f"boundary = {toml_value(name)}", f"{groups[name]:.3g} m"),
        ("flow = 0.5", "per metre per second, in the unit of rho_max x m/s (persons/(m s) with persons/m^2)"),
        ("# start = 0.0", "s"), ("# end = 60.0", "s (default: time.end)"))]
    return [
        f"# femcrowd case written by `femcrowd new` for {mesh_file.name}.",
        "# Keys left out take their default (see the case-format documentation). Run it with",
        f"#   femcrowd run {case_dir}",
        f"title = {toml_value(case_dir.resolve().name)}",
        "", "[mesh]",
        (f"file = {toml_value(relative)}", "gmsh .msh (2.2 or 4.1), relative to this file"),
        (f'refine = {_default("mesh", "refine")}', "uniform refinements after loading (convergence studies)"),
        "", "[boundary]",
        f"# boundary groups of the mesh: {group_list}",
        (f"exits = {toml_value(exits)}", "groups that are exits; every other boundary edge is a wall"),
        (f"# capacity = {{ {(exits + inside + ['exit'])[0]} = 1.9 }}",
         "persons/(m s) a door (an exit or an interior line) lets through at most"),
        "", "[model]",
        (f'type = {_default("model", "type")}', '"macro" (density) | "micro" (discs)'),
        (f'rho_max = {_default("model", "rho_max")}', "saturation density in your unit, e.g. 5.0 (people/m^2)"),
        "", ("[velocity]", "desired velocity U"), *velocity,
        "", "[initial]",
        ("density = 0.5", 'unit of rho_max: number or expression in x, y, e.g. "0.8 * (x < 4)"'),
        ("# [initial.regions]", f"or per surface group ({', '.join(surfaces) or 'none'}): crowd = 0.9"),
        *sources,
        "", "[time]",
        (f"end = {end:g}.0", f"s (the floor is {x1 - x0:.3g} m x {y1 - y0:.3g} m)"),
        (f'cfl = {_default("time", "cfl")}', "time step from the CFL number of the desired velocity"),
        ("# dt = 0.01", "or a fixed time step (s)"),
        (f'stop_when_empty = {_default("time", "stop_when_empty")}', "stop once everybody has left"),
        "", "[output]",
        (f'dir = {_default("output", "dir")}', "relative to this file"),
        (f'every = {_default("output", "every")}', "s between frames"),
        f'fields = {_default("output", "fields")}',
        "", ("# [micro]", 'model.type = "micro" only'),
        (f'# radius = {_default("micro", "radius")}', "m, or [min, max] for a polydisperse crowd"),
        f'# seed = {_default("micro", "seed")}',
    ]


def _stair_speeds(domain) -> list:
    """A building's (docs/floors.md) commented velocity.speeds line, naming its stairs (the sloped surface groups);
    no line for a plane floor plan."""
    if domain.z is None:
        return []
    t, pieces = domain.triangles, domain.mesh.subdomains or {}
    stairs = [name for name, cells in pieces.items() if np.ptp(domain.z[t[cells]]) > 0]
    return [(f"# speeds = {{ {', '.join(f'{name} = 0.6' for name in stairs)} }}",
             "m/s along each stair's slope: give your figure (docs/floors.md)")]


def _recommended(lines: list, domain) -> list:
    """The paper's lines with the recommended settings (studies/recommended.py) in place of the paper's: each
    line that changes is found by its key, and replaced by the lines of CHANGED."""
    exits, _, inside = door_groups(domain)
    area = domain.area.sum()
    widths = [domain.length[domain.groups[name]].sum() for name in exits]
    changed = {
        "rho_max": [("rho_max = 5.4", "persons/m^2; the paper's model: rho_max = 1.0")],
        "speed": [(f"speed = {toml_value(FREE_SPEED)}", "m/s: the law's free speed, 100 m/min; number or expression "
                   "in x, y"),
                  (f"speed_law = {toml_value(LAW['velocity.speed_law'])}", "slower in a dense crowd (Predtechenskii, "
                   'Milinskii 1978); the paper\'s: "constant"'),
                  (f"walls = {toml_value(WALLS['velocity.walls'])}", "no desired direction into a wall (docs/model.md, "
                   '"Walls"); the paper\'s: "paper"')],
        "# speed_law": [], "# push": [],
        "cfl": [(f"cfl = {STEP['time.cfl']}", "the whole CFL step of the speed law's fluxes: as accurate as 0.5 "
                 "in half the steps (docs/performance.md)")],
        "density": [(f"density = {DENSITY}", f"persons/m^2 ({DENSITY * area:.0f} people): number or expression "
                     'in x, y, e.g. "2.0 * (x < 4)"'),
                    (f"# people = {DENSITY * area:.0f}", "or a number of persons: the density is then their shape")],
        "flow": [("flow = 0.5", "persons per metre per second (or rate, persons/s; or people)")],
        "# seed": [lines[_index(lines, "# seed")], ('# strategy = "decelerate"', "the recommended discs "
                                                     "(docs/validation.md), with [velocity] speed = "
                                                     f'{WEIDMANN_SPEED}, speed_law = "weidmann", push = {PUSH}'),
                   f"# fluctuation = {FLUCTUATION}"],
    }
    if exits or inside:
        changed["# capacity"] = [(f"capacity = {toml_value({name: DOOR_CAPACITY for name in exits + inside})}",
                                  "persons/(m s) each door lets through at most: that of its width (2.08 up to "
                                  "1.2 m, 2.57 from 2.4 m), or a number")]
    if widths:   # the run ends after the walk and the drain of the crowd through the exits at their capacity
        walk = lines[_index(lines, "end")]
        passed = sum(width_capacity(w) * w for w in widths)
        end = 10.0 * math.ceil((float(walk[0].split("=")[1]) + DENSITY * area / passed) / 10.0)
        changed["end"] = [(f"end = {end:g}.0", f"{walk[1]}; the crowd through the exits at their capacity")]
    out = [lines[0], "# The recommended settings of docs/validation.md (the paper's model: --model paper)."]
    for line in lines[1:]:
        out += changed.get(_key(line), [line])
    return out


def _key(line) -> str:
    """The key a line sets (commented out: with its "# "), or the line."""
    return (line[0] if isinstance(line, tuple) else line).split(" =")[0]


def _index(lines, key: str) -> int:
    """The index of the line that sets `key`."""
    return next(i for i, line in enumerate(lines) if _key(line) == key)
