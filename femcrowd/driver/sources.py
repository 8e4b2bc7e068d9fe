"""Inflow sources (``[[sources]]``): people arriving through a boundary group at a flow per metre, a rate for the
whole group (each a number, an expression of t or a table: femcrowd/profiles.py) or a number of people.

The sources of a case are read and checked here (the group exists, is a boundary group, not an exit), and
turned into what each model does with them: the mass that enters the density (macro/inflow.py) and the discs
that enter through slots behind the entrance (micro/arrivals.py).
"""

import math
from dataclasses import dataclass

import numpy as np

from ..case import Case
from ..errors import InputError
from ..macro.inflow import Inflow
from ..mesh import Domain
from ..micro.arrivals import Arrivals
from ..micro.sampling import HEX_PACKING
from ..profiles import Profile


@dataclass
class Source:
    """One [[sources]] table on the mesh: its facets (boundary facets of the group) and their total length
    `width`; its arrivals g(t) = `profile` over [start, end], per metre of the group (flow) or, if `counted`, for
    the whole group (rate, people: persons per second)."""

    key: str
    boundary: str
    profile: Profile
    counted: bool
    start: float
    end: float
    population: str | None
    facets: np.ndarray
    width: float
    people: float | None = None

    @property
    def per_metre(self) -> float:
        """The level of the flow per metre (persons/(m s) x the profile's shape)."""
        return self.profile.level / self.width if self.counted else self.profile.level

    def label(self, unit: str) -> str:
        """What arrives, for pictures: "0.5 persons/(m s)" (unit: of a flow per metre), "2 persons/s",
        "200 persons", "persons/(m s) = 1 + sin(t)", "persons/s: a table of 4 points"."""
        if self.people is not None:
            return f"{self.people:g} persons"
        value, per = self.profile.value, "persons/s" if self.counted else f"{unit}/(m s)"
        if isinstance(value, list):
            return f"{per}: a table of {len(value)} points"
        if isinstance(value, str):
            return f"{per} = {value}"
        return f"{value:g} {per}"


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
        given = [k for k in ("flow", "rate", "people") if spec[k] is not None]
        if not given:
            raise InputError(case.file, f"{key}.flow", None, "missing required key: give one of flow "
                             "(persons/(m s)), rate (persons/s) and people (a number of persons)")
        if len(given) > 1:
            raise InputError(case.file, key, {k: spec[k] for k in given}, "give only one of flow (persons/(m s)), "
                             "rate (persons/s) and people (a number of persons)")
        what = given[0]
        profile = None if what == "people" else Profile(spec[what], (case.file, f"{key}.{what}"))
        last = math.inf if profile is None else profile.last   # a table's arrivals end with it
        end = min(case["time"]["end"], last) if spec["end"] is None else spec["end"]
        if end <= spec["start"]:
            raise InputError(case.file, f"{key}.end", end, f"must be after start = {spec['start']:g}"
                             + (" (the table's last time when end is not given)" if spec["end"] is None else ""))
        if profile is None:
            profile = Profile(spec["people"] / (end - spec["start"]))
        profile.check(spec["start"], end)
        sources.append(Source(key, name, profile, what != "flow", spec["start"], end, spec["population"],
                              np.asarray(facets), float(domain.length[facets].sum()), spec["people"]))
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
    rate = np.concatenate([s.per_metre / rho_max * domain.length[s.facets] for s in sources])
    population = np.array([population_index(case, s, populations) for s in sources])[owner]
    return Inflow(domain, facets, owner, rate, population, [s.profile for s in sources],
                  [(s.start, s.end) for s in sources], len(populations))


def micro_arrivals(case: Case, sources, domain: Domain, radius, walls, seed: int = 1, populations=("crowd",)):
    """The discs that the sources bring into a micro run (micro/arrivals.py). A flow g (density unit x m/s) is
    g / rho_max x packing / (pi E[r^2]) discs per metre per second, the conversion of the initial sampling
    (saturation rho_max = the hexagonal packing); a rate and a number of people count discs (one a person)."""
    lo, hi = (radius, radius) if np.isscalar(radius) else radius
    per_metre = HEX_PACKING / (np.pi * (lo * lo + lo * hi + hi * hi) / 3.0) / case["model"]["rho_max"]
    rates = [s.profile.level if s.counted else s.profile.level * per_metre * domain.length[s.facets].sum()
             for s in sources]
    return Arrivals(domain, [s.facets for s in sources], rates, [s.profile for s in sources],
                    [population_index(case, s, populations) for s in sources], [(s.start, s.end) for s in sources],
                    radius, walls, seed)
