"""People arriving through boundary facets (``[[sources]]``, docs/scenes.md): the mass that enters the density,
a hook of MacroSolver before each prediction.

Each source facet e brings rate_e x the integral of the source's g(t) / level over [t, t + dt] & [start, end] into
its queue during a step (rate_e = level x |e| per metre, in units of rho_max x m^2 per second; femcrowd/profiles.py;
a constant flow: rate_e |[t, t + dt] & [start, end]|). What fits enters the cell K behind e, up to its room
|K| (1 - rho_K) shared in proportion to the queues of the facets of K; the rest waits outside and enters at
a later step. An explicit prediction carries what entered from the step's start (MacroSolver.add_source). An
implicit one takes it in its solve, a boundary inflow over the step, and its room is larger by what the step
carries out of K when rho~_K = 1 (the transports' ``drain``): a free stream enters whole at any step, and its
density is q / v from the first cell on (docs/scenes.md, "Sources at a large step"). Hence, per step and exactly,
arrived = inflow + queued, and mass(t) + evacuated(t) = mass(0) + inflow(t).
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..profiles import amounts


class Inflow:
    """The before_step hook of a macro run's sources: each source facet's cell, rate (mass per second at the
    level of its profile) and population, the profile (femcrowd/profiles.py) and span [start, end] of each source
    (``owner``: the source of each facet); inflow and queued in units of rho_max x m^2."""

    def __init__(self, domain, facets, owner, rate, population, profiles, spans, populations: int):
        self.domain = domain
        self.cells = domain.f2t[0][facets]
        self.owner, self.rate, self.population, self.profiles = owner, rate, population, profiles
        self.start, self.end = np.asarray(spans, float).reshape(-1, 2).T
        self.target = population * domain.ncells + self.cells   # flat index into rho (populations, cells)
        self.queue = np.zeros(len(facets))
        self.arrived = np.zeros(populations)   # per population
        self._part = None   # (doors, the connected part of each cell): _parts

    def __call__(self, solver, state, dt: float) -> None:
        """Add what arrives during [t, t + dt] and fits to state.rho; the rest stays queued."""
        self.queue += self.rate * amounts(self.profiles, self.start, self.end, state.t, dt)[self.owner]
        if not self.queue.any():
            return
        n = self.domain.ncells
        area = self.domain.area
        demand = np.bincount(self.cells, self.queue, n)
        room = np.maximum(area * (1.0 - state.density), 0.0)
        drain = solver.drain(state, dt)
        if drain is not None:   # an implicit step: the arrivals enter its solve
            room += self._beyond(room, drain, solver.boundary.at(state.t))
        with np.errstate(divide="ignore", invalid="ignore"):
            fraction = np.where(demand > room, room / demand, 1.0)
        enter = self.queue * fraction[self.cells]
        self.queue -= enter
        density = np.bincount(self.target, enter, state.rho.size) / np.tile(area, len(state.rho))
        solver.add_source(state, density.reshape(state.rho.shape))
        self.arrived += np.bincount(self.population, enter, len(self.arrived))

    def _beyond(self, free, drain, exits) -> np.ndarray:
        """The room of each source cell beyond its own free space |K| (1 - rho_K) in an implicit step: what the step
        carries out of K when rho~_K = 1 (``drain``, the least of its facets' populations), scaled down in each part
        of the floor between walls and capped doors to the free space of its other cells, so that the projection can
        always place what enters (a jam reaching the source: the explicit step's room)."""
        extra = np.full(self.domain.ncells, np.inf)
        np.minimum.at(extra, self.cells, drain[self.population, self.cells])
        extra = np.where(np.isfinite(extra), extra, 0.0)
        part = self._parts(exits)
        own = np.zeros(self.domain.ncells)
        own[self.cells] = free[self.cells]
        spare = np.bincount(part, free - own)
        wanted = np.bincount(part, extra, len(spare))
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(wanted > spare, spare / wanted, 1.0)
        return extra * scale[part]

    def _parts(self, exits) -> np.ndarray:
        """The connected parts of the floor across the facets that are neither walls nor capped doors (per set of
        open doors: the cells a correction can reach from a source)."""
        if self._part is None or self._part[0] is not exits:
            domain = self.domain
            joined = domain.interior & (exits.transmissibility > 0)
            if exits.caps is not None:
                joined[exits.caps.facets] = False
            k0, k1 = domain.f2t[0][joined], domain.f2t[1][joined]
            graph = sp.coo_matrix((np.ones(len(k0)), (k0, k1)), shape=(domain.ncells,) * 2)
            self._part = (exits, connected_components(graph, directed=False)[1])
        return self._part[1]

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
