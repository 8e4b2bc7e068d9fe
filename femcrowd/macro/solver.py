"""The macroscopic solver: one catching-up step, prediction + correction (Maury, Roudneff-Chupin,
Santambrogio 2010; docs/model.md).

    rho~      = transport of each population rho_i^n by its U_i over tau   (transport/)
    rho^{n+1} = projection of the total rho~ onto {rho <= 1}               (projection/, phi = tau p)
    u^{n+1}   = U - grad p                                                  (reconstruction.py, for output)

on the doors open at t^n (mesh/boundary.py): a door with a capacity caps the prediction and joins the
projection as door nodes (mesh/capacity.py). Densities are in units of rho_max (rho = 1 is
saturation); the driver converts to and from the user's unit. Hooks run before the prediction
(sources) and after the correction (measurements).

A population with a speed law (U = f(rho) U0, speed_law.py) is transported with the LWR fluxes
(transport/lwr.py); when no population pushes at saturation (f(1) = 0 for all) the density never
exceeds 1 and the projection is never built nor called. Several populations share the correction
by an implicit upwind split of its facet fluxes (populations.py).
"""

from dataclasses import dataclass

import numpy as np

from ..step import Step
from ..timer import Stopwatch, Timer
from .populations import split_correction
from .projection import CellOrder, PressureFlux, Projection
from .reconstruction import CellMean, actual_velocity
from .seen_density import SeenDensity
from .speed_law import SpeedLaw
from .state import MacroState
from .transport import IMPLICIT, LWR_TRANSPORTS, TRANSPORTS
from .transport.capped import capped_step
from .transport.implicit import ImplicitLWRTransport
from .transport.lwr import LWRTransport, joint_max_dt
from .transport.muscl_lwr import facet_fluxes, stages
from .velocity import CongestionVelocity


@dataclass
class MacroStep(Step):
    """A step of the density (iterations: the projection's active-set iterations): linear_residual and unknowns
    of its projection, the projection's counters and seconds (``Projection.__call__``), the pressure flux of the
    correction, and the doors with a capacity ({door: (flow, pressure)}, Capacities.report; None without)."""

    linear_residual: float
    unknowns: int
    projection: dict
    flux: PressureFlux
    doors: dict | None = None


class MacroSolver:
    """Catching-up steps of a MacroState (PyClaw's Solver), with the operators of each set of open exits
    built once: the Laplacian's projection and the transport (rebuilt every step for a U that depends on
    t); ``before_step`` hooks f(solver, state, dt), ``after_step`` hooks f(solver, state, step) (its
    MacroStep)."""

    def __init__(self, domain, boundary, velocities, transport="upwind", cfl=0.5, dt=None,
                 direct_max=1_000_000, tol=1e-12, laws=None, quantile=0.0):
        """velocities: the desired velocity U0 of each population (femcrowd.macro.velocity); laws: the
        speed law of each population (femcrowd.macro.speed_law.SpeedLaw, None or "constant": f = 1);
        quantile: the cell whose CFL-1 step cfl multiplies (``time.cfl_quantile``; 0: the smallest)."""
        self.domain, self.boundary, self.velocities = domain, boundary, list(velocities)
        self.routing = [v for v in self.velocities if isinstance(v, CongestionVelocity)]
        seen = SeenDensity(domain)   # what Hughes' cost sees (factorised on first use), one for all populations
        for velocity in self.routing:
            velocity.seen = seen
        self.laws = [None if law is None or law.constant else law for law in (laws or [None] * len(self.velocities))]
        self.implicit = transport in IMPLICIT
        self.transport_class = TRANSPORTS[transport]
        self.lwr_class = LWR_TRANSPORTS.get(transport, LWRTransport)
        #: False when every population has f(1) = 0 and the LWR step is the explicit order-0 one (bounded): the
        #: density stays <= 1 without the projection
        self.needs_projection = (self.implicit or not self.lwr_class.bounded
                                 or any(law is None or law.saturates for law in self.laws))
        #: the populations step together (muscl with a speed law: each stage's law sees the stage's total)
        self.together = self.lwr_class.together and any(law is not None for law in self.laws)
        self.cfl, self.fixed_dt, self.quantile = cfl, dt, quantile
        self.direct_max, self.tol = direct_max, tol
        self.order = CellOrder()  # one nested-dissection order for the projections of every set of exits
        self.before_step, self.after_step = [], []
        self.timers = Timer()
        self._projections = {}    # per set of open exits: (Projection, outflow matrix of the pressure flux)
        self._transports = None   # (exits, the velocities' versions, one transport per population)
        self._open = None         # the open exits of the last projection (a door that changed: no warm start)
        self._cell_mean = None    # the RT0 cell means of all cells (the output velocity), assembled once
        self._normals = {}        # per CellMean: (exits, the velocities' versions, U_i . n on its facets)
        self._source = None       # the density arriving in the coming implicit prediction (add_source)

    def transports(self, state: MacroState, exits) -> list:
        """The transport of each population at the state's time, on these exits."""
        versions = tuple(v.version(state, exits) for v in self.velocities)
        built = self._transports
        if built is None or built[0] is not exits or built[1] != versions:
            # the cap of an interior door in the implicit solve needs its flows, and implicit-godunov is its own
            # scheme for f = 1 too: f = 1 as the linearly implicit scheme (solved in the order of the flow)
            every = self._caps_in_solve(exits) or self.lwr_class.every_law or self.together
            constant = SpeedLaw("constant") if every else None
            schemes = [self.lwr_class(self.domain, exits, v.normal_on_facets(state, exits), law or constant)
                       if law is not None or constant is not None
                       else self.transport_class(self.domain, exits, v.normal_on_facets(state, exits),
                                                 v.potential(exits))
                       for v, law in zip(self.velocities, self.laws)]
            self._transports = built = (exits, versions, schemes)
        return built[2]

    def _caps_in_solve(self, exits) -> bool:
        """Whether the prediction has the caps of interior doors in its solve (the implicit transport,
        transport/capped.py); the other transports cut after the step (mesh/capacity.py)."""
        return (issubclass(self.lwr_class, ImplicitLWRTransport) and exits.caps is not None
                and bool(np.any(exits.caps.receiver >= 0)))

    def projection(self, exits) -> Projection:
        """The projection onto {rho <= 1} with these doors (open exits Dirichlet, capacities as door nodes),
        built once per set of open exits."""
        if exits.open not in self._projections:
            self._projections[exits.open] = Projection(self.domain, exits, self.direct_max, self.tol,
                                                       order=self.order)
        elif exits.open != self._open:   # back to a door state met before: its S and phi are stale
            self._projections[exits.open].warm.forget()
        self._open = exits.open
        return self._projections[exits.open]

    def stable_dt(self, state: MacroState) -> float:
        """Largest step allowed: cfl * (CFL-1 step of the upwind scheme), or the fixed dt. The CFL-1 step is that
        of the smallest cell, or with a quantile q > 0 (implicit transport only) the q-quantile of the cells'
        (docs/model.md, "Steps by accuracy").

        A fixed dt is checked against the CFL limit at setup; it is still capped here
        (at the transport's own max_cfl) because a time-dependent U can lower the limit
        during the run, and beyond it the upwind update has negative coefficients
        (negative densities, lost mass).
        """
        schemes = self.transports(state, self.boundary.at(state.t))
        lwr = [s for s in schemes if type(s) is LWRTransport]   # the explicit ones
        # the bound of the total density takes every population's flux into a cell
        joint = joint_max_dt(self.domain, lwr) if len(lwr) > 1 else np.inf
        if self.fixed_dt is None:
            return self.cfl * min(min(s.courant_dt(self.quantile) for s in schemes), joint)
        return min(self.fixed_dt, min(s.max_cfl * s.max_dt for s in schemes), joint)

    def add_source(self, state: MacroState, density: np.ndarray) -> None:
        """Arrivals of the coming step, (populations, cells) in density (sources, macro/inflow.py): an explicit
        prediction carries them from the step's start (added to state.rho, as the paper's scheme); an implicit one
        takes them in its solve, the term |K| source_K / tau of its right-hand side (a boundary inflow over the
        step: they enter as the step's fluxes carry people on)."""
        if self.implicit:
            self._source = density if self._source is None else self._source + density
        else:
            state.rho += density

    def drain(self, state: MacroState, dt: float) -> np.ndarray | None:
        """(populations, cells): what the coming implicit prediction carries out of each cell when its density ends
        at 1 (the transports' ``drain``), which a source's cell adds to |K| (1 - rho_K) (macro/inflow.py); None for
        an explicit transport, whose fluxes carry the density at the step's start."""
        if not self.implicit:
            return None
        schemes = self.transports(state, self.boundary.at(state.t))
        return np.array([scheme.drain(rho, dt, *extra)
                         for scheme, rho, extra in zip(schemes, state.rho, self._seen(state, schemes))])

    def step(self, state: MacroState, until: float = np.inf) -> MacroStep:
        """Advance the state by one step, not beyond time ``until`` (a shorter step lands on it: the controller
        passes the frame times and the door changes); return its MacroStep."""
        clock = Stopwatch()
        if self.routing:
            with self.timers("route"):   # the route choice, re-solved when it is due
                for velocity in self.routing:
                    velocity.route(state.t, state.density, self.boundary.at(state.t))
        with self.timers("transport"):   # with the step's set-up and the hooks before it
            exits = self.boundary.at(state.t)
            schemes = self.transports(state, exits)
            dt = self.stable_dt(state)
            t_new = state.t + dt
            if t_new >= until:
                dt, t_new = until - state.t, until
            for hook in self.before_step:
                hook(self, state, dt)
            rho_tilde, outflow, passed = self._predict(state, schemes, exits, dt)
            self._source = None
        with self.timers("projection"):   # with the state update and the hooks after it
            result = self._correct_step(state, rho_tilde, outflow, passed, exits, dt, t_new)
            result.seconds = clock.seconds
        return result

    def _predict(self, state, schemes, exits, dt):
        """rho~ of each population, the mass out through each exit and the net mass through the capped doors
        (capped by the doors, mesh/capacity.py)."""
        rho_tilde = np.empty_like(state.rho)
        outflow = np.zeros_like(state.evacuated)
        caps = exits.caps
        through = np.zeros((len(schemes), 0 if caps is None else len(caps.facets)))
        for i, prediction in enumerate(self._predictions(state, schemes, exits, dt)):
            rho_tilde[i], outflow[i], through[i] = prediction
        passed = None if caps is None else caps.limit(rho_tilde, outflow, through, dt, self.domain.area)
        return rho_tilde, outflow, passed

    def _predictions(self, state, schemes, exits, dt) -> list:
        """The Prediction of each population before the doors' cut: with the caps of the interior doors in the
        solve of the implicit transport (transport/capped.py), else each population's step."""
        if self.together:
            return stages(schemes, state.rho, dt)
        seen = self._seen(state, schemes)
        sources = self._sources(state)
        if self._caps_in_solve(exits):
            return capped_step(schemes, state.rho, dt, seen, exits.caps, sources)[0]
        return [scheme.step(rho, dt, *extra, **arriving(source))
                for scheme, rho, extra, source in zip(schemes, state.rho, seen, sources)]

    def _sources(self, state: MacroState) -> list:
        """The density arriving in the coming prediction per population (add_source), None for none."""
        return [None] * len(state.rho) if self._source is None else list(self._source)

    def _correct_step(self, state, rho_tilde, outflow, passed, exits, dt, t_new) -> MacroStep:
        """The correction of the step and the new state; the step's diagnostics (the after_step hooks run on
        them)."""
        caps = exits.caps
        if self.needs_projection:
            total = rho_tilde[0] if len(rho_tilde) == 1 else rho_tilde.sum(axis=0)
            flux, info = self.projection(exits)(total, None if caps is None else caps.room(passed, dt))
            state.rho, pushed_out = self._correct(rho_tilde, flux, exits)
            outflow += pushed_out
        else:
            empty = np.zeros(0, np.intp)
            flux, info = PressureFlux(np.zeros(self.domain.ncells), empty, np.zeros(0)), Projection.counters()
            state.rho = rho_tilde
        state.p = flux.phi / dt
        if self.boundary.capped:
            state.jump = flux.jump / dt if flux.jump is not None else np.zeros(len(self.domain.length))
        state.evacuated += outflow
        state.t = t_new
        state.steps += 1
        doors = None if caps is None else caps.report(passed, flux.facet_flux(self.domain, exits, caps.facets),
                                                       flux.door, dt)
        result = MacroStep(t_new, dt, 0.0, info["iterations"], info["linear_residual"], info["unknowns"], info,
                           flux, doors)
        for hook in self.after_step:
            hook(self, state, result)
        return result

    def facet_flux(self, state: MacroState, dt: float, facets=None) -> np.ndarray:
        """The mass each facet (of `facets`, default all) carries f2t[0] -> f2t[1] in the coming prediction of all
        populations (measurement lines; their before-step hook calls it once the sources are added)."""
        exits = self.boundary.at(state.t)
        schemes = self.transports(state, exits)
        facets = np.arange(len(self.domain.length)) if facets is None else facets
        seen = self._seen(state, schemes)
        if self.together:
            flux = facet_fluxes(schemes, state.rho, dt, facets)
        elif self._caps_in_solve(exits):   # the prediction of the step, its interior doors capped in the solve
            predictions = self._predictions(state, schemes, exits, dt)
            flux = sum(scheme.facet_flux(rho, dt, *extra, facets=facets, predicted=p.rho)
                       for scheme, rho, extra, p in zip(schemes, state.rho, seen, predictions))
        else:
            flux = sum(scheme.facet_flux(rho, dt, *extra, facets=facets, **arriving(source))
                       for scheme, rho, extra, source in zip(schemes, state.rho, seen, self._sources(state)))
        if exits.caps is not None:   # the doors' cap of the step (mesh/capacity.py)
            cap = np.zeros(len(self.domain.length))
            cap[exits.caps.facets] = exits.caps.rate * dt
            capped = np.isin(facets, exits.caps.facets)
            flux[capped] = np.clip(flux[capped], -cap[facets[capped]], cap[facets[capped]])
        return flux

    @staticmethod
    def _seen(state: MacroState, schemes):
        """The extra argument of each population's prediction: the total density its speed law sees
        (several populations with a speed law), else nothing."""
        total = (state.density,) if len(schemes) > 1 else ()
        return [total if isinstance(s, LWRTransport) else () for s in schemes]

    def _correct(self, rho_tilde, flux, exits):
        """rho^{n+1} and the mass the correction pushes out through each exit, per population: for one
        population rho~ - (A phi) / |K|; for several the implicit upwind split (populations.py)."""
        if len(rho_tilde) == 1:
            return flux.apply(rho_tilde[0], self.domain.area)[None], exits.pressure_outflow(flux.phi, flux.jump)[None]
        total = flux.apply(rho_tilde.sum(axis=0), self.domain.area)
        return split_correction(self.domain, exits, flux, rho_tilde, total)

    def velocity_field(self, state: MacroState, mean: CellMean | None = None) -> np.ndarray:
        """Actual velocity u = U - grad p per cell (of ``mean``, default all), U = f(rho) U0 (the mean of the
        populations' U_i weighted by their shares of the cell's density)."""
        if mean is None:
            if self._cell_mean is None:
                self._cell_mean = CellMean(self.domain)
            mean = self._cell_mean
        exits, facets = self.boundary.at(state.t), mean.facets
        normals = self._desired_normals(state, exits, mean)
        if len(self.velocities) == 1 and self.laws[0] is None:
            return actual_velocity(self.domain, exits, normals[0], state.p, state.jump, mean)
        rho = state.density
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(rho > 0, state.rho / rho, 1.0 / len(state.rho))
        k0, k1 = self.domain.f2t[0][facets], self.domain.f2t[1][facets]
        sides = (k0, np.where(k1 >= 0, k1, k0))
        normal = 0.0
        for i, law in enumerate(self.laws):
            weight = share[i] * (law(rho) if law is not None else 1.0)
            normal = normal + np.stack([weight[k] for k in sides]) * normals[i]
        return actual_velocity(self.domain, exits, normal, state.p, state.jump, mean)

    def _desired_normals(self, state, exits, mean: CellMean) -> list:
        """U_i . n on the facets of ``mean``, per population; kept while the doors and the U_i stay the same."""
        versions = tuple(v.version(state, exits) for v in self.velocities)
        kept = self._normals.get(mean)
        if kept is None or kept[0] is not exits or kept[1] != versions:
            kept = self._normals[mean] = (exits, versions,
                                          [v.normal_on_facets(state, exits, mean.facets) for v in self.velocities])
        return kept[2]


def arriving(source) -> dict:
    """The keyword of a prediction for the density arriving in it (an implicit transport's; none: no keyword, as the
    explicit transports take)."""
    return {} if source is None else {"source": source}
