"""Inflow sources (``[[sources]]``): people arriving through a boundary group at a given flow per metre.

The sources of a case are read and checked here (the group exists, is a boundary group, not an exit), and
turned into what each model does with them: the mass that enters the density (macro/inflow.py) and the discs
that enter through slots behind the entrance (micro/arrivals.py).
"""

from dataclasses import dataclass

import numpy as np

from ..case import Case
from ..errors import InputError
from ..macro.inflow import Inflow
from ..mesh import Domain
from ..micro.arrivals import Arrivals
from ..micro.sampling import HEX_PACKING


@dataclass
class Source:
    """One [[sources]] table on the mesh: its facets (boundary facets of the group), their cells and lengths."""

    key: str
    boundary: str
    flow: float
    start: float
    end: float
    population: str | None
    facets: np.ndarray


def read_sources(case: Case, domain: Domain) -> list:
    """The [[sources]] of a case, checked against the mesh (group exists, is a boundary group, not an exit)."""
    sources = []
    for i, spec in enumerate(case["sources"]):
        key, name = f"sources[{i}]", spec["boundary"]
        if name not in domain.groups:
            raise InputError(case.file, f"{key}.boundary", name, "no boundary group of that name in the mesh "
                             f"(groups: {', '.join(domain.groups) or 'none'})")
        if name in domain.exit_names:
            raise InputError(case.file, f"{key}.boundary", name, "is an exit: people arrive through a group "
                             "that is not one of boundary.exits")
        facets = domain.groups[name]
        if not len(facets) or domain.interior[facets].any():
            raise InputError(case.file, f"{key}.boundary", name, "must be made of boundary edges")
        end = case["time"]["end"] if spec["end"] is None else spec["end"]
        if end <= spec["start"]:
            raise InputError(case.file, f"{key}.end", end, f"must be after start = {spec['start']:g}")
        sources.append(Source(key, name, spec["flow"], spec["start"], end, spec["population"], np.asarray(facets)))
    return sources


def population_index(case: Case, source: Source, populations) -> int:
    """The index of a source's population in the state (the first when the source names none)."""
    if source.population is None:
        return 0
    if source.population not in populations:
        raise InputError(case.file, f"{source.key}.population", source.population,
                         f"no such population (populations: {', '.join(populations)})")
    return list(populations).index(source.population)


def macro_inflow(case: Case, sources, domain: Domain, populations) -> Inflow:
    """The mass that the sources bring into a macro run (macro/inflow.py), in units of rho_max."""
    rho_max = case["model"]["rho_max"]
    facets = np.concatenate([s.facets for s in sources])
    owner = np.concatenate([np.full(len(s.facets), k) for k, s in enumerate(sources)])
    rate = np.concatenate([s.flow / rho_max * domain.length[s.facets] for s in sources])
    population = np.array([population_index(case, s, populations) for s in sources])[owner]
    return Inflow(domain, facets, owner, rate, population, [(s.start, s.end) for s in sources], len(populations))


def micro_arrivals(case: Case, sources, domain: Domain, radius, walls, seed: int = 1, populations=("crowd",)):
    """The discs that the sources bring into a micro run (micro/arrivals.py). A flow g (density unit x m/s) is
    g / rho_max x packing / (pi E[r^2]) discs per metre per second, the conversion of the initial sampling
    (saturation rho_max = the hexagonal packing)."""
    lo, hi = (radius, radius) if np.isscalar(radius) else radius
    per_metre = HEX_PACKING / (np.pi * (lo * lo + lo * hi + hi * hi) / 3.0) / case["model"]["rho_max"]
    return Arrivals(domain, [s.facets for s in sources], [s.flow * per_metre * domain.length[s.facets].sum()
                                                           for s in sources],
                    [population_index(case, s, populations) for s in sources], [(s.start, s.end) for s in sources],
                    radius, walls, seed)
