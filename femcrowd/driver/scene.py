"""A case turned into a scene, the same for both models: the floor plan, its exits over time, the desired
velocity, the initial crowd (pyro2's problem set-up, apart from the solvers).

Everything that can fail on bad input (mesh, exits, expressions, initial density, discs) is
checked here, before the output directory is touched, so a bad case never overwrites results.
"""

import difflib
from dataclasses import dataclass, field

import numpy as np

from ..case import Case
from ..errors import InputError
from ..macro.transport import IMPLICIT
from ..mesh import Boundary, Domain, load_domain
from ..mesh.capacity import width_capacity
from ..micro.sampling import overlaps, read_discs_csv, sample_discs
from ..timer import Timer
from .measurements import read_measurements
from .plausibility import warn_implausible
from .populations import build_populations, initial_densities
from .sources import read_sources


@dataclass
class Scene:
    """The case, its domain, the doors over time (boundary), the set-up phases' timer, the populations
    (driver/populations.py: desired velocity and speed law of each), and the sources, measurement lines and
    areas (empty lists when the case has none)."""

    case: Case
    domain: Domain
    boundary: Boundary
    timer: Timer = field(default_factory=Timer)
    populations: list = field(default_factory=list)
    sources: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    areas: list = field(default_factory=list)


def build_scene(case: Case, plan=None) -> Scene:
    """Load the mesh and build the desired velocity of each population (timed: mesh, desired_velocity; the
    plausibility warnings: checks); plan: a run's Plan (driver/limits.py), told the mesh's size before it is
    refined."""
    timer = Timer()
    with timer("mesh"):
        domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"],
                             case["mesh"]["refine"], case.file, plan.mesh if plan is not None else None)
        if domain.z is not None:
            check_building(case)
        boundary = Boundary(domain, door_schedule(case, domain), door_capacity(case, domain))
        sources = read_sources(case, domain)
        lines, areas = read_measurements(case, domain)
    with timer("desired_velocity"):
        populations = build_populations(case, domain, boundary)
    scene = Scene(case, domain, boundary, timer, populations, sources, lines, areas)
    with timer("checks"):
        warn_implausible(scene)
    return scene


#: what a case on a building (docs/floors.md) may not use yet: key -> (the values it may have, why)
NOT_ON_BUILDINGS = {
    ("scheme", "transport"): (("upwind", *IMPLICIT), "on a building only the upwind transports, explicit and "
                                                     "implicit, are on the surface yet (muscl and compressive "
                                                     "reconstruct in plan; docs/floors.md)"),
    ("measure", "lines"): (([],), "measurement lines are located in plan, where the floors overlap (docs/floors.md)"),
    ("measure", "areas"): (([],), "measurement areas are located in plan, where the floors overlap (docs/floors.md)"),
}


#: what the discs on a building (docs/floors.md, "Discs on stairs") may not use yet: key -> (its values then, why)
DISCS_NOT_ON_BUILDINGS = {
    ("velocity", "type"): (("exits",), "the discs of a building walk by the walking distance on its surface only "
                                       "(docs/floors.md)"),
    ("velocity", "route"): (("shortest",), "the discs' route choice sees their density in plan, where the floors "
                                           "overlap (docs/floors.md)"),
    ("micro", "positions"): ((None,), "a file of disc centres gives no floor: give the crowd by initial.regions "
                                      "(docs/floors.md)"),
    ("sources", None): (([],), "discs arriving on a building are not placed on its surface yet (docs/floors.md)"),
}


def check_building(case: Case) -> None:
    """InputError for the first key whose value a run on a building does not support yet (NOT_ON_BUILDINGS, and
    DISCS_NOT_ON_BUILDINGS for the disc model)."""
    rules = {**NOT_ON_BUILDINGS, **(DISCS_NOT_ON_BUILDINGS if case["model"]["type"] == "micro" else {})}
    for (section, key), (allowed, why) in rules.items():
        value = case[section] if key is None else case[section][key]
        if value not in allowed:
            raise InputError(case.file, section if key is None else f"{section}.{key}", value, why)


def door_schedule(case: Case, domain: Domain) -> dict:
    """[boundary.open], its names checked against the exits."""
    schedule = case["boundary"]["open"]
    for name, spans in schedule.items():
        if name not in domain.exit_names:
            raise InputError(case.file, f"boundary.open.{name}", spans, "is not an exit (boundary.exits: "
                             f"{', '.join(domain.exit_names) or 'none'})")
    return schedule


#: the transports that take a capacity on an interior door: those whose every stage is one explicit upwind step
#: (the cut gives back to the cell behind the door at most what the step brought it, mesh/capacity.py) and the
#: implicit ones (the cap in their solve, macro/transport/capped.py)
INTERIOR_CAPS = ("upwind", "compressive", *IMPLICIT)


def door_capacity(case: Case, domain: Domain) -> dict:
    """[boundary.capacity], its names checked against the mesh (an exit, or an interior line group), in units of
    rho_max x m/s; "auto": the capacity of the door's width (its length in the mesh, mesh/capacity.py)."""
    capacity = case["boundary"]["capacity"]
    for name, value in capacity.items():
        key = f"boundary.capacity.{name}"
        if name not in domain.groups:
            close = difflib.get_close_matches(name, list(domain.groups), n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise InputError(case.file, key, value, f"no line group of that name in the mesh ({hint}groups: "
                             f"{', '.join(domain.groups) or 'none'})")
        if name in domain.exit_group:
            continue
        if not np.all(domain.interior[domain.groups[name]]):
            raise InputError(case.file, key, value, f"{name!r} has boundary edges but is not an exit: a door with a "
                             "capacity is an exit (boundary.exits) or a line between two rooms")
        if case["scheme"]["transport"] not in INTERIOR_CAPS:
            raise InputError(case.file, key, value, "a capacity on an interior door needs a one-stage or the "
                             f"implicit transport (scheme.transport = {' or '.join(map(repr, INTERIOR_CAPS))})")
    width = {name: float(domain.length[domain.groups[name]].sum()) for name in capacity}
    persons = {name: width_capacity(width[name]) if value == "auto" else value for name, value in capacity.items()}
    return {name: value / case["model"]["rho_max"] for name, value in persons.items()}


def initial_discs(case: Case, domain: Domain, exits, rho=None, surface=None) -> tuple[np.ndarray, np.ndarray]:
    """(q, r) of the disc model: from the CSV of [micro].positions, or sampled without overlap from the
    initial density (clear of the walls and exits of `exits`); rho: the cell densities in units of rho_max
    (default: [initial]); surface: the Atlas of a building (micro/surface.py), whose layout q is then in, each
    disc clear of the folds too (on one piece)."""
    spec = case["micro"]
    if spec["positions"] is not None:
        people, key = disc_count(case)
        if people is not None:
            raise InputError(case.file, key, people, "the discs are those of micro.positions: give no number of "
                             "people with it")
        return _discs_csv(case, domain, exits)
    rho = initial_densities(case, domain).sum(axis=0) if rho is None else rho  # cell values, scaled to [0, 1]
    people, key = disc_count(case)
    count = spec["count"] if people is None else people
    if surface is None:
        locate, points, triangles = domain.locate, domain.points, domain.triangles
        walls, ends = exits.segments("wall"), exits.segments("exit")
    else:
        locate, points, triangles = surface.locate, surface.points, surface.triangles
        walls = np.concatenate([surface.segments(exits.wall, True),
                                *[np.stack(list(fold["segment"].values())) for fold in surface.folds]])
        ends = surface.segments(exits.exit, False)
    try:
        q, r = sample_discs(lambda xy: rho[np.maximum(locate(xy), 0)], points, triangles, spec["radius"], count,
                            walls=walls, exits=ends, seed=spec["seed"], strict=people is not None)
    except ValueError as err:   # strict: fewer discs fit than the people asked for
        raise InputError(case.file, key, people, str(err)) from None
    if len(q) == 0 and not case["sources"]:
        raise InputError(case.file, "initial.density", case["initial"]["density"],
                         "gives no discs (an empty crowd)")
    return q, r


def disc_count(case: Case) -> tuple:
    """(the number of discs the people keys ask for, the key to name), or (None, None) without them: initial.people,
    or the sum of populations.<name>.people, which every population then gives; not with micro.count."""
    people = {f"populations.{name}.people": spec["people"] for name, spec in case["populations"].items()}
    people = people or {"initial.people": case["initial"]["people"]}
    given = {key: n for key, n in people.items() if n is not None}
    if not given:
        return None, None
    key = next(iter(given))
    if len(given) < len(people):
        missing = next(k for k in people if k not in given)
        raise InputError(case.file, missing, None, f"the discs need a number of people for every population, as "
                         f"{key} gives")
    if case["micro"]["count"] is not None:
        raise InputError(case.file, "micro.count", case["micro"]["count"], f"give the discs by {key} or by "
                         "micro.count, not both")
    fraction = [k for k, n in given.items() if n != round(n)]
    if fraction:
        raise InputError(case.file, fraction[0], given[fraction[0]], "the discs need a whole number of people")
    return sum(round(n) for n in given.values()), key


def _discs_csv(case: Case, domain: Domain, exits) -> tuple[np.ndarray, np.ndarray]:
    """(q, r) of the CSV of [micro].positions: InputError naming its line and values for a disc whose centre is
    outside the domain, that crosses a wall (a door closed at t = 0 included) or overlaps another disc (by more
    than 1e-9 r: touching is allowed), before anything is written."""
    name = case["micro"]["positions"]
    q, r, line = read_positions(case)

    def disc(k):
        return f"line {line[k]} (x = {q[k, 0]:g}, y = {q[k, 1]:g}, r = {r[k]:g})"

    outside = np.flatnonzero(domain.locate(q) < 0)
    if len(outside):
        raise InputError(case.file, "micro.positions", name, f"{len(outside)} disc centres lie outside the domain, "
                         f"the first at {disc(outside[0])}")
    i, j, overlap = overlaps(q, r, exits.segments("wall"))
    if len(i):
        clash = (f"the disc of {disc(i[0])} crosses a wall" if j[0] < 0 else
                 f"the discs of {disc(i[0])} and {disc(j[0])} overlap")
        more = f" ({len(i)} overlaps in all)" if len(i) > 1 else ""
        raise InputError(case.file, "micro.positions", name, f"{clash} by {overlap[0]:.3g} m{more}: discs must not "
                         "overlap one another nor cross a wall (touching is allowed)")
    return q, r


def read_positions(case: Case) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, r, line in the file) of the CSV of [micro].positions; InputError naming it for a file that cannot be
    read or holds bad values."""
    name = case["micro"]["positions"]
    try:
        return read_discs_csv(case.path(name), lines=True)
    except (OSError, ValueError) as err:
        raise InputError(case.file, "micro.positions", name, getattr(err, "strerror", None) or str(err)) from None


def check_transport_cfl(case: Case, transport) -> None:
    """Refuse a time step beyond the transport's own CFL number (max_cfl: 1 for upwind, beyond
    which densities can become negative; 0.5 for the higher-order transports, beyond which
    they oscillate; 100 for the implicit ones, positive at any step).

    transport: the transport object, or its class when the case has no time.dt."""
    name, limit, dt, cfl = case["scheme"]["transport"], transport.max_cfl, case["time"]["dt"], case["time"]["cfl"]
    if not 0 < cfl <= limit:
        raise InputError(case.file, "time.cfl", cfl, f"must be in (0, {limit:g}] with scheme.transport = {name!r}")
    quantile = case["time"]["cfl_quantile"]
    if quantile and name not in IMPLICIT:
        raise InputError(case.file, "time.cfl_quantile", quantile, f"must be 0 with scheme.transport = {name!r}: "
                         "an explicit step stays positive only within the CFL step of the smallest cell")
    if quantile and dt is not None:
        raise InputError(case.file, "time.cfl_quantile", quantile, "sets the step of time.cfl: not with time.dt")
    if dt is not None and dt > limit * transport.max_dt:
        raise InputError(case.file, "time.dt", dt, f"exceeds {limit:g} x the CFL limit "
                         f"{transport.max_dt:.3g} s of the upwind scheme, the most scheme.transport = "
                         f"{name!r} allows (use a smaller dt, or time.cfl)")
