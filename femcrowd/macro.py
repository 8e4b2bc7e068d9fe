"""The macroscopic solver: catching-up scheme, prediction + correction (design note, sec. 2).

    rho~      = transport of rho^n by U over tau          (UpwindTransport)
    rho^{n+1} = projection of rho~ onto {rho <= 1}         (Projection, phi = tau p)
    u^{n+1}   = U - grad p                                 (for output)

Densities are stored scaled by rho_max (rho = 1 is saturation); setup and I/O
convert to the user's unit.
"""

import time
from collections import defaultdict

import numpy as np

from .projection import Projection, cell_mean, velocity_correction
from .transport import CompressiveTransport, MUSCLTransport, UpwindTransport, exit_matrix

SATURATED = 1.0 - 1e-9  # rho above this counts as saturated (the solver tolerance)
#: [scheme] transport: order-0 upwind; linear reconstruction + SSP-RK2; the same with one Euler stage
TRANSPORTS = {"upwind": UpwindTransport, "muscl": MUSCLTransport, "compressive": CompressiveTransport}


class MacroSolver:
    """State (t, rho, p, evacuated, evacuated per exit group) and one catching-up step."""

    def __init__(self, domain, velocity, rho0, cfl=0.5, dt=None, projection=None, transport="upwind"):
        self.domain, self.velocity = domain, velocity
        self.cfl, self.fixed_dt = cfl, dt
        self.t, self.step_count = 0.0, 0
        self.rho = np.array(rho0, float)
        self.p = np.zeros_like(self.rho)
        self.evacuated = 0.0
        self.exit_names = list(domain.exit_group)
        self.evacuated_by_exit = np.zeros(len(self.exit_names))
        self.initial_mass = self.mass
        self.projection = projection or Projection(domain)
        self.exit_transmissibility = exit_matrix(domain, domain.transmissibility)  # outflow T_e phi_K
        self.transport_class = TRANSPORTS[transport]  # [scheme] transport
        self.transport = self.transport_class(domain, velocity.normal_on_facets(0.0))
        self.timers = defaultdict(float)

    @property
    def mass(self):
        return float(self.domain.area @ self.rho)

    def stable_dt(self):
        """Largest step allowed: cfl * (CFL-1 step of the upwind scheme), or the fixed dt.

        A fixed dt is checked against the CFL limit at setup; it is still capped here
        (at the transport's own max_cfl) because a time-dependent U can lower the limit
        during the run, and beyond it the upwind update has negative coefficients
        (negative densities, lost mass).
        """
        limit = self.transport.max_cfl * self.transport.max_dt
        return self.cfl * self.transport.max_dt if self.fixed_dt is None else min(self.fixed_dt, limit)

    def step(self, until=np.inf):
        """Advance by one step, not beyond time ``until``; return the step's diagnostics."""
        tic = time.perf_counter()
        if not self.velocity.steady:
            self.transport = self.transport_class(self.domain, self.velocity.normal_on_facets(self.t))
        dt = self.stable_dt()
        t_new = self.t + dt
        if t_new >= until:
            dt, t_new = until - self.t, until
        rho_tilde, out_transport = self.transport.step(self.rho, dt)
        toc = time.perf_counter()
        self.rho, phi, info = self.projection(rho_tilde)
        out = out_transport + self.exit_transmissibility @ phi  # per exit group
        self.timers["transport"] += toc - tic
        self.timers["projection"] += time.perf_counter() - toc
        self.p = phi / dt
        self.evacuated_by_exit += out
        self.evacuated += float(out.sum())
        self.t = t_new
        self.step_count += 1
        return {"dt": dt, "active_set_iterations": info["iterations"],
                "linear_residual": info["linear_residual"], "unknowns": info["unknowns"],
                "step_seconds": time.perf_counter() - tic}

    def velocity_field(self):
        """Actual velocity u = U - grad p per cell: the RT0 cell mean of the scheme's facet fluxes,
        |e| U.n (none through walls) plus the pressure fluxes. Hence u.n = 0 on walls and u = 0
        where nothing moves (a closed saturated room); U(centroid) - grad p is O(1) wrong there
        in the cells along the walls, whose U.n the scheme never transports."""
        flux = np.where(self.domain.wall, 0.0, self.velocity.normal_on_facets(self.t)) * self.domain.length
        return cell_mean(self.domain, *flux) + velocity_correction(self.domain, self.p)

    def diagnostics(self):
        """Invariants of the design note for the current state (scaled units)."""
        rho, p, area = self.rho, self.p, self.domain.area
        saturated = rho >= SATURATED
        unsaturated_p = p[~saturated]
        return {
            "mass": self.mass, "evacuated": self.evacuated,
            "max_density": float(rho.max()), "min_density": float(rho.min()),
            "saturated_area": float(area[saturated].sum()),
            "max_pressure": float(p.max()), "min_pressure": float(p.min()),
            "pressure_unsaturated": float(np.abs(unsaturated_p).max()) if unsaturated_p.size else 0.0,
            "complementarity": float(np.max(np.abs(p * (1.0 - rho)))),
        }
