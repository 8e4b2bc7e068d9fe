"""Inflow sources (``[[sources]]``): people arriving through a boundary group at a given flow per metre.

A source on the boundary group G with flow g (persons per metre per second, the case's density
unit x m/s) between ``start`` and ``end`` brings g |e| |[t, t + dt] & [start, end]| into the
queue of each facet e of G during a step. What fits enters the cell K behind e before the
prediction, up to its room |K| (1 - rho_K) (shared in proportion to the queues of the facets
of K); the rest waits outside and enters at a later step (docs/scenes.md, "People arriving": what
cannot enter waits outside and is counted). Hence, per step and exactly,

    arrived = inflow + queued,   mass(t) + evacuated(t) = mass(0) + inflow(t).

Micro runs place discs in slots one radius behind the entrance (random sequential addition,
as the initial sampling does): a disc enters when a slot is free of discs; the others wait.
"""

import json
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..case import Case
from ..errors import InputError
from ..mesh import Domain
from ..micro.contacts import WallSet
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

    def window(self, t: float, dt: float) -> float:
        """Length of [t, t + dt] inside [start, end]."""
        return max(0.0, min(t + dt, self.end) - max(t, self.start))


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


class MacroSources:
    """The before_step hook of the sources of a macro run; inflow and queued in units of rho_max x m^2."""

    def __init__(self, case: Case, sources, domain: Domain, populations):
        rho_max = case["model"]["rho_max"]
        self.sources = sources
        self.domain = domain
        self.facets = np.concatenate([s.facets for s in sources])
        self.cells = domain.f2t[0][self.facets]
        self.owner = np.concatenate([np.full(len(s.facets), k) for k, s in enumerate(sources)])
        self.rate = np.concatenate([s.flow / rho_max * domain.length[s.facets] for s in sources])
        pops = np.array([population_index(case, s, populations) for s in sources])
        self.population = pops[self.owner]   # of each source facet
        self.target = self.population * domain.ncells + self.cells   # flat index into rho (populations, cells)
        self.queue = np.zeros(len(self.facets))
        self.arrived = np.zeros(len(populations))   # per population

    def __call__(self, solver, state, dt: float) -> None:
        """Add what arrives during [t, t + dt] and fits to state.rho; the rest stays queued."""
        windows = np.array([s.window(state.t, dt) for s in self.sources])
        self.queue += self.rate * windows[self.owner]
        if not self.queue.any():
            return
        n = self.domain.ncells
        area = self.domain.area
        demand = np.bincount(self.cells, self.queue, n)
        room = np.maximum(area * (1.0 - state.density), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            fraction = np.where(demand > room, room / demand, 1.0)
        enter = self.queue * fraction[self.cells]
        self.queue -= enter
        rho = state.rho.reshape(-1)   # a view: (populations, cells) flattened
        rho += np.bincount(self.target, enter, rho.size) / np.tile(area, len(state.rho))
        self.arrived += np.bincount(self.population, enter, len(self.arrived))

    @property
    def inflow(self) -> float:
        """What entered so far, all populations."""
        return float(self.arrived.sum())

    @property
    def queued(self) -> float:
        return float(self.queue.sum())

    def snapshot(self) -> dict:
        return {"queue": self.queue.copy(), "arrived": self.arrived.copy()}

    def restore(self, data: dict) -> None:
        self.queue, self.arrived = data["queue"].copy(), data["arrived"].copy()


class MicroSources:
    """Discs arriving through the sources of a micro run: slots behind each entrance, filled when free.

    A flow g (density unit x m/s) is g / rho_max x packing / (pi E[r^2]) discs per metre per second,
    the conversion of the initial sampling (saturation rho_max = the hexagonal packing).
    """

    def __init__(self, case: Case, sources, domain: Domain, radius, walls, seed: int = 1, populations=("crowd",)):
        lo, hi = (radius, radius) if np.isscalar(radius) else radius
        self.populations = [population_index(case, s, populations) for s in sources]
        self.r = float(hi)   # slots fit the largest disc; arrivals get radii drawn like the initial ones
        self.radius = (float(lo), float(hi))
        mean_square = (lo * lo + lo * hi + hi * hi) / 3.0
        per_metre = HEX_PACKING / (np.pi * mean_square) / case["model"]["rho_max"]
        self.sources = sources
        self.rate = [s.flow * per_metre * domain.length[s.facets].sum() for s in sources]
        self.slots = [self._slots(domain, s.facets, WallSet(walls)) for s in sources]
        self.pending = np.zeros(len(sources))
        self.rng = np.random.default_rng(seed)
        self.inflow = 0

    def _slots(self, domain, facets, walls) -> np.ndarray:
        """Disc centres 1.01 r behind the facets, at least 2 r apart, clear of every wall (set-up only)."""
        r, out = self.r, []
        for f in facets:
            a, b = domain.points[domain.mesh.facets[:, f]]
            n = int(np.ceil(4 * np.linalg.norm(b - a) / r))
            s = (np.arange(n) + 0.5) / n
            out.append(a + s[:, None] * (b - a) - 1.01 * r * domain.normal[f])
        candidates = np.concatenate(out)
        if walls.n:
            hit, _, _, dist = walls.near(candidates, r)
            clear = np.ones(len(candidates), bool)
            clear[hit[dist < r]] = False
            candidates = candidates[clear]
        kept = []   # greedy thinning along the entrance: a handful of slots, once
        for c in candidates[np.lexsort(candidates.T[::-1])]:
            if not kept or np.min(np.linalg.norm(np.array(kept) - c, axis=1)) >= 2 * r:
                kept.append(c)
        return np.array(kept).reshape(-1, 2)

    def arrivals(self, t: float, dt: float, q: np.ndarray, r: np.ndarray):
        """Centres, radii and population indices of the discs that enter during [t, t + dt] next to the
        discs (q, r)."""
        self.pending += [rate * s.window(t, dt) for rate, s in zip(self.rate, self.sources)]
        wanted = np.floor(self.pending + 1e-9).astype(int)
        if not wanted.any():
            return np.zeros((0, 2)), np.zeros(0), np.zeros(0, int)
        tree = cKDTree(q) if len(q) else None
        reach = self.r + (r.max() if len(r) else 0.0)
        new_q, new_r, new_p = [], [], []
        for k, slots in enumerate(self.slots):
            if not wanted[k] or not len(slots):
                continue
            free = np.ones(len(slots), bool)
            if tree is not None:
                dd, jj = tree.query(slots, k=min(8, len(q)), distance_upper_bound=reach)
                dd, jj = dd.reshape(len(slots), -1), jj.reshape(len(slots), -1)
                valid = jj < len(q)
                free = ~(valid & (dd < r[np.minimum(jj, len(q) - 1)] + self.r)).any(axis=1)
            chosen = self.rng.permutation(np.flatnonzero(free))[:wanted[k]]
            new_q.append(slots[chosen])
            lo, hi = self.radius
            new_r.append(np.full(len(chosen), lo) if lo == hi else self.rng.uniform(lo, hi, len(chosen)))
            new_p.append(np.full(len(chosen), self.populations[k]))
            self.pending[k] -= len(chosen)
        q_in = np.concatenate(new_q) if new_q else np.zeros((0, 2))
        r_in = np.concatenate(new_r) if new_r else np.zeros(0)
        p_in = np.concatenate(new_p).astype(int) if new_p else np.zeros(0, int)
        self.inflow += len(q_in)
        return q_in, r_in, p_in

    @property
    def queued(self) -> float:
        return float(np.floor(self.pending + 1e-9).sum())

    def snapshot(self) -> dict:
        return {"pending": self.pending.copy(), "inflow": self.inflow,
                "rng": json.dumps(self.rng.bit_generator.state)}

    def restore(self, data: dict) -> None:
        self.pending, self.inflow = data["pending"].copy(), int(data["inflow"])
        self.rng.bit_generator.state = json.loads(str(data["rng"]))
