"""The populations of a scene (docs/extensions.md; case-format.md, "Extensions"): each with its name, its
desired velocity U0 (a [velocity] table in which the keys of its [populations.<name>] table override
the case's), its speed law f(rho) and its initial density. A case without [populations] has one,
"crowd", made of [velocity] and [initial]: nothing else changes for it.

Everything is checked here, before the output directory is touched: a population heading for an
exit that is not one, densities that sum above rho_max, expressions that give non-finite values, a speed
that would make people walk away from the exits.
"""

from dataclasses import dataclass

import numpy as np

from ..case import Case, Expression
from ..errors import InputError
from ..macro.speed_law import SpeedLaw
from ..macro.stairs import Climbs, speed_value
from ..macro.velocity import CongestionVelocity, ExitsVelocity, FieldVelocity
from ..mesh import Boundary, Domain

#: the one population of a case without [populations]
CROWD = "crowd"
#: the keys of [velocity] that a population may override
VELOCITY_KEYS = ("type", "speed", "speed_law", "push", "ux", "uy")


@dataclass
class Population:
    """One population: its name, desired velocity U0 (femcrowd.macro.velocity) and speed law."""

    name: str
    velocity: object
    law: SpeedLaw


def desired_velocity(case: Case, domain: Domain, boundary: Boundary, spec=None, key=None,
                     targets=None) -> FieldVelocity | ExitsVelocity | CongestionVelocity:
    """The [velocity] of the case (or `spec`, a population's velocity table, its keys named by key(name));
    for type "exits" (towards the exits `targets`, default all) the distance field of the exits open at
    t = 0 is computed here (set-up), those of other door states when they first occur; with route =
    "congestion" the potential is solved at the first step, from the density then."""
    spec = case["velocity"] if spec is None else spec
    key = key or (lambda name: f"velocity.{name}")
    if spec["type"] == "field":
        where = np.vstack([domain.centroid, domain.midpoint])
        ux, uy = (Expression(spec[k], origin=(case.file, key(k))) for k in ("ux", "uy"))
        for u in (ux, uy):
            u(*where.T)   # once at t = 0: a value that is not finite is refused at load time
        return FieldVelocity(domain, ux, uy)
    if not domain.exit_group:
        raise InputError(case.file, key("type"), "exits",
                         "needs at least one exit (set boundary.exits) or use type = 'field'")
    speed = Expression(spec["speed"], origin=(case.file, key("speed")))
    if speed.depends_on_time:
        raise InputError(case.file, key("speed"), spec["speed"],
                         "must not depend on t for type = 'exits'")
    values = speed(*domain.centroid.T)
    if values.min() < 0:
        raise InputError(case.file, key("speed"), spec["speed"],
                         f"is negative ({values.min():.3g}) somewhere: people would walk away from the exits "
                         "(for such a scene give U itself: type = 'field')")
    if case["velocity"]["route"] == "congestion":
        law = SpeedLaw(spec["speed_law"], case["model"]["rho_max"], spec["push"], (case.file, key("speed_law")))
        velocity = CongestionVelocity(domain, speed, targets, law, case["velocity"]["route_every"],
                                      case["velocity"]["walls"], case["velocity"]["clearance"])
        region_speeds(case, domain, velocity)
        return velocity
    velocity = ExitsVelocity(domain, speed, targets, case["velocity"]["walls"], case["velocity"]["clearance"])
    region_speeds(case, domain, velocity)
    velocity.cells(boundary.at(0.0))
    return velocity


def region_speeds(case: Case, domain: Domain, velocity: ExitsVelocity) -> None:
    """velocity.speeds: the desired speed per physical surface group (a stair's), written into the cells' speed; a
    stair's { up = ..., down = ... } into velocity.climbs, the speed of each cell then chosen by the direction U
    takes there (macro/stairs.py). A speed is a number (m/s) or the name of a published one (STAIR_SPEEDS)."""
    subdomains = domain.mesh.subdomains or {}
    cells, up, down = [], [], []
    for name, value in case["velocity"]["speeds"].items():
        key = f"velocity.speeds.{name}"
        if name not in subdomains:
            raise InputError(case.file, key, value,
                             f"no surface group of that name (groups: {', '.join(subdomains) or 'none'})")
        group = np.asarray(subdomains[name])
        if not isinstance(value, dict):
            velocity.speed[group] = speed_value(value)
            continue
        if domain.slope is None or not np.any(domain.slope[group]):
            raise InputError(case.file, key, value, "up and down speeds need a stair (a sloped surface group); "
                             "give one speed")
        cells.append(group)
        up.append(np.full(len(group), speed_value(value["up"])))
        down.append(np.full(len(group), speed_value(value["down"])))
        velocity.speed[group] = np.minimum(up[-1], down[-1])
    if cells:
        velocity.climbs = Climbs(np.concatenate(cells), np.concatenate(up), np.concatenate(down))


def initial_density(case: Case, domain: Domain, source=None, key="initial.density", people=None,
                    people_key="initial.people") -> np.ndarray:
    """Cell averages of the initial density (or of `source`, a population's, named `key`), scaled by rho_max;
    with `people` (named `people_key`) the density is the shape of a crowd of that many persons."""
    rho_max = case["model"]["rho_max"]
    source = case["initial"]["density"] if source is None else source
    density = domain.cell_average(Expression(source, origin=(case.file, key)))
    subdomains = domain.mesh.subdomains or {}
    for name, value in case["initial"]["regions"].items() if key == "initial.density" else ():
        if name not in subdomains:
            raise InputError(case.file, f"initial.regions.{name}", value,
                             f"no surface group of that name (groups: {', '.join(subdomains) or 'none'})")
        if not 0 <= value <= rho_max:
            raise InputError(case.file, f"initial.regions.{name}", value, f"is outside [0, rho_max = {rho_max:g}]")
        density[np.asarray(subdomains[name])] = value
    low, high = float(density.min()), float(density.max())
    if low < 0 or people is None and high > rho_max * (1 + 1e-12):
        bad = low if low < 0 else high
        raise InputError(case.file, key, source, f"density {bad:g} is outside [0, rho_max = {rho_max:g}]")
    if people is not None:
        density = counted(case, domain, density, people, people_key)
    return np.minimum(density / rho_max, 1.0)


def counted(case: Case, domain: Domain, shape: np.ndarray, people: float, key: str) -> np.ndarray:
    """The cell densities (persons/m^2) of `people` persons spread as `shape` (>= 0; uniform if 0 everywhere):
    sum of density x area = people; InputError naming `key` if the densest cell would exceed rho_max."""
    rho_max = case["model"]["rho_max"]
    shape = shape if shape.any() else np.ones_like(shape)
    density = shape * (people / (shape @ domain.area))
    if density.max() > rho_max * (1 + 1e-12):
        most = people * rho_max / density.max()
        raise InputError(case.file, key, people, f"persons do not fit under rho_max = {rho_max:g} in the shape of the "
                         f"initial density (the densest place would hold {density.max():.4g} persons/m^2): at most "
                         f"{most:.6g}")
    return density


def build_populations(case: Case, domain: Domain, boundary: Boundary) -> list:
    """The populations of the case, their desired velocities built (distance fields of the exits open at 0)."""
    rho_max = case["model"]["rho_max"]
    common = case["velocity"]["type"]
    types = {spec["type"] or common for spec in case["populations"].values()} or {common}
    if case["velocity"]["route"] == "congestion" and "exits" not in types:
        raise InputError(case.file, "velocity.route", "congestion", "chooses the routes to the exits, but no "
                         "population has velocity type 'exits' (with type 'field', ux and uy are the velocity): "
                         'set velocity.type = "exits", or leave route out')
    if not case["populations"]:
        velocity = desired_velocity(case, domain, boundary)
        law = SpeedLaw(case["velocity"]["speed_law"], rho_max, case["velocity"]["push"],
                       (case.file, "velocity.speed_law"))
        return [Population(CROWD, velocity, law)]
    initial = case["initial"]
    if initial["density"] != 0.0 or initial["regions"] or initial["people"] is not None:
        key = next(f"initial.{k}" for k in ("density", "regions", "people") if initial[k] not in (0.0, {}, None))
        raise InputError(case.file, key, initial[key.split(".")[1]], "with [populations] each population has its "
                         "own initial density and people (populations.<name>.density, populations.<name>.people)")
    populations = []
    for name, spec in case["populations"].items():
        table = f"populations.{name}"
        own = {k for k in VELOCITY_KEYS if spec[k] is not None}
        merged = {k: spec[k] if k in own else case["velocity"][k] for k in VELOCITY_KEYS}

        def key(k, own=own, table=table):
            return f"{table}.{k}" if k in own else f"velocity.{k}"

        targets = spec["exits"]
        if targets is not None:
            bad = [e for e in targets if e not in domain.exit_names]
            if bad or not targets:
                what = f"{bad[0]!r} is not an exit of the case" if bad else "is empty"
                raise InputError(case.file, f"{table}.exits", targets,
                                 f"{what} (boundary.exits: {', '.join(domain.exit_names) or 'none'})")
        velocity = desired_velocity(case, domain, boundary, merged, key, targets)
        law = SpeedLaw(merged["speed_law"], rho_max, merged["push"], (case.file, key("speed_law")))
        populations.append(Population(name, velocity, law))
    return populations


def initial_densities(case: Case, domain: Domain) -> np.ndarray:
    """(populations, cells) initial densities in units of rho_max; their sum is at most 1."""
    if not case["populations"]:
        return initial_density(case, domain, people=case["initial"]["people"])[None]
    rho = np.array([initial_density(case, domain, spec["density"], f"populations.{name}.density", spec["people"],
                                    f"populations.{name}.people") for name, spec in case["populations"].items()])
    total = rho.sum(axis=0)
    if total.max() > 1 + 1e-12:
        k = int(np.argmax(total))
        x, y = domain.centroid[k]
        rho_max = case["model"]["rho_max"]
        raise InputError(case.file, "populations", {n: s["density"] for n, s in case["populations"].items()},
                         f"the initial densities sum to {total[k] * rho_max:.6g} > rho_max = {rho_max:g} "
                         f"at ({x:.3g}, {y:.3g})")
    return rho


def disc_populations(case: Case, domain: Domain, rho: np.ndarray, q: np.ndarray, locate=None) -> np.ndarray:
    """The population index of each disc centred at q: drawn with the populations' shares of the initial
    density of its cell (rho: (populations, cells)), seeded by micro.seed; with populations.<name>.people,
    exactly that many discs each (drawn in turn without replacement, in proportion to the shares); locate: the
    cells of the discs' centres (default domain.locate; a building's Atlas.locate)."""
    if len(rho) == 1:
        return np.zeros(len(q), int)
    cell = np.maximum((locate or domain.locate)(q), 0)
    share = rho[:, cell].T
    total = share.sum(axis=1, keepdims=True)
    share = np.divide(share, total, out=np.full_like(share, 1.0 / len(rho)), where=total > 0)
    rng = np.random.default_rng(case["micro"]["seed"])
    people = [spec["people"] for spec in case["populations"].values()]
    if people[0] is not None and case["micro"]["positions"] is None:   # disc_count: all or none give people
        return _exact_populations(share, [round(n) for n in people], rng)
    draw = rng.random(len(q))
    return np.minimum((draw[:, None] > np.cumsum(share, axis=1)).sum(axis=1), len(rho) - 1)


def _exact_populations(share: np.ndarray, counts: list, rng) -> np.ndarray:
    """Population indices with counts[k] discs in population k: each population but the last draws its discs
    from those left, in proportion to its share of their cells (the last takes the rest)."""
    population = np.full(len(share), len(counts) - 1)
    left = np.arange(len(share))
    for k, n in enumerate(counts[:-1]):
        weight = share[left, k] + 1e-300   # a disc where k has no share is drawn only when nothing else is left
        chosen = rng.choice(len(left), size=n, replace=False, p=weight / weight.sum())
        population[left[chosen]] = k
        left = np.delete(left, chosen)
    return population
