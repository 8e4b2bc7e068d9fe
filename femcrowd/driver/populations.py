"""The populations of a scene (docs/extensions.md; case-format.md, "Extensions"): each with its name, its
desired velocity U0 (a [velocity] table in which the keys of its [populations.<name>] table override
the case's), its speed law f(rho) and its initial density. A case without [populations] has one,
"crowd", made of [velocity] and [initial]: nothing else changes for it.

Everything is checked here, before the output directory is touched: a population heading for an
exit that is not one, densities that sum above rho_max, and the velocity checks of scene.py.
"""

from dataclasses import dataclass

import numpy as np

from ..case import Case
from ..errors import InputError
from ..macro.speed_law import SpeedLaw
from ..mesh import Boundary, Domain
from .scene import desired_velocity, initial_density

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


def build_populations(case: Case, domain: Domain, boundary: Boundary) -> list:
    """The populations of the case, their desired velocities built (distance fields of the exits open at 0)."""
    rho_max = case["model"]["rho_max"]
    if not case["populations"]:
        velocity = desired_velocity(case, domain, boundary)
        return [Population(CROWD, velocity, SpeedLaw(case["velocity"]["speed_law"], rho_max,
                                                      case["velocity"]["push"]))]
    initial = case["initial"]
    if initial["density"] != 0.0 or initial["regions"]:
        key = "initial.density" if initial["density"] != 0.0 else "initial.regions"
        raise InputError(case.file, key, initial[key.split(".")[1]],
                         "with [populations] each population has its own initial density (populations.<name>.density)")
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
        populations.append(Population(name, velocity, SpeedLaw(merged["speed_law"], rho_max, merged["push"])))
    return populations


def initial_densities(case: Case, domain: Domain) -> np.ndarray:
    """(populations, cells) initial densities in units of rho_max; their sum is at most 1."""
    if not case["populations"]:
        return initial_density(case, domain)[None]
    rho = np.array([initial_density(case, domain, spec["density"], f"populations.{name}.density")
                    for name, spec in case["populations"].items()])
    total = rho.sum(axis=0)
    if total.max() > 1 + 1e-12:
        k = int(np.argmax(total))
        x, y = domain.centroid[k]
        rho_max = case["model"]["rho_max"]
        raise InputError(case.file, "populations", {n: s["density"] for n, s in case["populations"].items()},
                         f"the initial densities sum to {total[k] * rho_max:.6g} > rho_max = {rho_max:g} "
                         f"at ({x:.3g}, {y:.3g})")
    return rho


def disc_populations(case: Case, domain: Domain, rho: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The population index of each disc centred at q: drawn with the populations' shares of the initial
    density of its cell (rho: (populations, cells)), seeded by micro.seed."""
    if len(rho) == 1:
        return np.zeros(len(q), int)
    cell = np.maximum(domain.locate(q), 0)
    share = rho[:, cell].T
    total = share.sum(axis=1, keepdims=True)
    share = np.divide(share, total, out=np.full_like(share, 1.0 / len(rho)), where=total > 0)
    draw = np.random.default_rng(case["micro"]["seed"]).random(len(q))
    return np.minimum((draw[:, None] > np.cumsum(share, axis=1)).sum(axis=1), len(rho) - 1)
