"""``[scheme] transport = "implicit"``: backward-Euler upwind transport, positive and conservative at any
time step.

    (|K| / tau) (rho~_K - rho_K) = (F rho~)_K,    i.e.    (I - tau diag(1/|K|) F) rho~ = rho,

with F the upwind flux balance of the explicit scheme (upwind.py). |K| I - tau F is an M-matrix
whose every column sums to |K| plus tau times the exit outflow rate of K (the fluxes are
conservative), so it is strictly diagonally dominant by columns: its inverse is >= 0, rho~ >= 0
for any tau, and sum_K |K| rho~_K + tau outflow(rho~) = sum_K |K| rho_K. Its numerical
diffusion grows with the CFL number: a larger step is cheaper, not more accurate (the catching-up
scheme's projection does not limit tau; docs/convergence.md measures the trade).

The linear system is solved by sparse LU (SuperLU), one factorisation per time step length. For a
desired velocity with a potential (U = -v grad d, d the distance to the exits) the cells are taken
in the order of decreasing d, where the matrix is triangular but for the few cells whose velocity
fans back: almost no fill, and a solve costs a few mat-vecs.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .flow_order import FlowOrder
from .lwr import LWRTransport, law_at
from .upwind import Prediction, UpwindTransport

#: the factorisations kept: the usual step and a shorter one (cut at a frame time)
KEPT = 2


class ImplicitUpwindTransport(UpwindTransport):
    """Backward-Euler upwind: (I - tau diag(1/|K|) F) rho~ = rho, by sparse LU."""

    max_cfl = 100.0  # positivity holds at any step; beyond this the smearing makes no sense

    def __init__(self, domain, exits, normal_velocity, potential=None):
        """potential: a cell field decreasing downstream (the distance to the exits), or None."""
        super().__init__(domain, exits, normal_velocity)
        self.order = None if potential is None else np.argsort(-potential, kind="stable")
        self._factors = {}  # dt -> LU of the system, in self.order

    def step(self, rho: np.ndarray, dt: float, source=None) -> Prediction:
        """rho~, the mass that left through each exit during dt and the net mass through the capped door
        facets (at the new density); source: the density that arrives during the step (sources, macro/inflow.py),
        the term |K| source_K / tau of the solve's right-hand side."""
        lu = self._factors.get(dt) or self._factorise(dt)
        rhs = rho if source is None else rho + source
        if self.order is None:
            rho_t = lu.solve(rhs)
        else:
            rho_t = np.empty_like(rho)
            rho_t[self.order] = lu.solve(rhs[self.order])
        np.maximum(rho_t, 0.0, out=rho_t)  # the inverse is >= 0: only round-off is clipped
        return Prediction(rho_t, dt * (self.exit_rate @ rho_t), self._carried(rho_t, dt, self.capped))

    def drain(self, rho: np.ndarray, dt: float) -> np.ndarray:
        """tau out_K per cell, what the step carries out of K when rho~_K = 1 (sources, macro/inflow.py): with an
        arrival a in K and no inflow from upstream, rho~_K = (rho_K + a / |K|) / (1 + tau out_K / |K|) <= 1 while
        a <= |K| (1 - rho_K) + tau out_K."""
        return dt * self.domain.area / self.cell_dt

    def facet_flux(self, rho: np.ndarray, dt: float, facets=slice(None), source=None) -> np.ndarray:
        """The mass each facet (of `facets`) carries in the step of rho by dt: the upwind fluxes of the new density
        rho~ (for measurement lines; it solves the step again, so step() keeps its cost when nobody measures)."""
        return self._carried(self.step(rho, dt, source).rho, dt, facets)

    def _factorise(self, dt):
        M = sp.identity(self.domain.ncells, format="csr") - sp.diags(dt / self.domain.area) @ self.flux
        if self.order is None:
            lu = spla.splu(M.tocsc(), permc_spec="COLAMD")
        else:
            lu = spla.splu(M[self.order][:, self.order].tocsc(), permc_spec="NATURAL")
        if len(self._factors) >= KEPT:
            self._factors.pop(min(self._factors))  # the shortest step goes first
        self._factors[dt] = lu
        return lu


class ImplicitLWRTransport(LWRTransport):
    """Linearly implicit (frozen-coefficient) LWR transport: the flux across each facet from the sender K to
    the receiver L is q_e rho~_K f(rho^n_L), the speed factor lagged at t^n (the downstream density, as the
    explicit scheme's flux rho_K f(rho_L), lwr.py), the density at t^{n+1}:

        (|K| / tau) (rho~_K - rho_K) = sum_{L -> K} q_e f(rho^n_K) rho~_L - sum_{K -> L} q_e f(rho^n_L) rho~_K

    (the semi-implicit upwind scheme of a conservation law with frozen coefficients, e.g. LeVeque 2002,
    Finite Volume Methods for Hyperbolic Problems, section 4.12, and the linearly implicit schemes of
    Ascher, Ruuth, Wetton 1995). Each step's matrix |K| I + tau (out - in) has the structure of
    ImplicitUpwindTransport's with the rates q_e f(rho^n_L) >= 0: an M-matrix, so rho~ >= 0 and the mass is
    conserved at any step; f = 1 gives the backward-Euler upwind scheme. A population i of several takes
    q_e rho~_i,K f(total^n_L). First order in time; the Godunov demand/supply flux is not used, and
    rho~ <= 1 is not kept even with f(1) = 0: the projection follows every step. The coefficients change
    with rho^n, the flow directions do not: the system is solved in the block triangular order of the flow
    (flow_order.py, built once per transport), a substitution where the flow has no cycle."""

    max_cfl = ImplicitUpwindTransport.max_cfl

    def __init__(self, domain, exits, normal_velocity, law):
        super().__init__(domain, exits, normal_velocity, law)
        self.inner = np.flatnonzero(self.receiver < domain.ncells)   # the flows between two cells
        self.flow_order = FlowOrder(self.sender[self.inner], self.receiver[self.inner], domain.ncells)
        door = self.receiver[self.capped_flows] < domain.ncells
        #: the flows across the capped interior doors and their positions among the capped facets (their cap is
        #: in the solve, capped.py; an exit's is the doors' cut after it, mesh/capacity.py)
        self.door_flows, self.door_position = self.capped_flows[door], self.capped_position[door]

    def flows(self, rho, total=None, which=slice(None)):
        """The mass rate of this population along each flow (of `which`): q_e rho_K f(total_L), total the density
        the speed law sees (default rho)."""
        total = rho if total is None else total
        seen = np.append(total, 0.0)   # the outside is empty
        return rho[self.sender[which]] * self.law(seen[self.receiver[which]]) * self.rate[which]

    def speeds(self, rho, total=None) -> np.ndarray:
        """The rate of each flow, q_e f(rho^n_L) (total^n_L with several populations)."""
        seen = np.append(rho if total is None else total, 0.0)
        return law_at(self.law, seen, self.receiver) * self.rate

    def share(self, dt, speed) -> np.ndarray:
        """omega_K, the implicit share of the fluxes out of each cell K: 1, backward Euler in every cell."""
        return np.ones(self.domain.ncells)

    def solve(self, rho, dt, speed, share, source=None) -> np.ndarray:
        """rho~ of the step whose flow e from K carries speed_e (omega_K rho~_K + (1 - omega_K) rho_K), omega the
        `share` of each cell:

            (|K| / tau + omega_K out_K) rho~_K - sum_{L -> K} omega_L speed_e rho~_L
                = (|K| / tau - (1 - omega_K) out_K) rho_K + |K| source_K / tau
                  + sum_{L -> K} (1 - omega_L) speed_e rho_L,

        out_K the sum of the speeds leaving K, source the density arriving during the step (sources,
        macro/inflow.py: it enters the implicit part, as a boundary inflow), in the order of the flow."""
        n, area, inner = len(rho), self.domain.area, self.inner
        out = np.bincount(self.sender, speed, n)
        sender, explicit = self.sender[inner], 1.0 - share
        held = rho if source is None else rho + source
        b = held * area / dt + np.bincount(self.receiver[inner], speed[inner] * (explicit * rho)[sender], n)
        rho_t = self.flow_order.solve(area / dt + share * out, -speed[inner] * share[sender], b - explicit * out * rho)
        np.maximum(rho_t, 0.0, out=rho_t)   # the inverse is >= 0: only round-off is clipped
        return rho_t

    def drain(self, rho, dt, total=None) -> np.ndarray:
        """tau out_K (omega_K + (1 - omega_K) rho_K) per cell, what the step carries out of K when rho~_K = 1
        (sources, macro/inflow.py): with an arrival a in K's solve and no inflow from upstream,
        rho~_K (|K| + tau omega_K out_K) = |K| rho_K - tau (1 - omega_K) out_K rho_K + a, at most |K| while
        a <= |K| (1 - rho_K) + tau out_K (omega_K + (1 - omega_K) rho_K)."""
        speed = self.speeds(rho, total)
        share = self.share(dt, speed)
        return dt * np.bincount(self.sender, speed, self.domain.ncells) * (share + (1.0 - share) * rho)

    def prediction(self, rho, rho_t, dt, speed, share) -> Prediction:
        """The Prediction of rho~ (from rho) carried by these speeds: the mass out through each exit and across
        each capped facet."""
        flux = carried(rho, rho_t, share)[self.sender] * speed
        evacuated = dt * np.bincount(self.exit_of_flow, flux[self.exit_flows], self.n_exits)
        through = dt * np.bincount(self.capped_position, self.flow_sign[self.capped_flows] * flux[self.capped_flows],
                                   len(self.capped))
        return Prediction(rho_t, evacuated, through)

    def step(self, rho, dt, total=None, source=None) -> Prediction:
        """rho~ of this population (with the density `source` arriving during the step, solve), the mass that left
        through each exit during dt and the net mass through the capped door facets (the fluxes of rho~ with the
        speed of t^n)."""
        speed = self.speeds(rho, total)
        share = self.share(dt, speed)
        return self.prediction(rho, self.solve(rho, dt, speed, share, source), dt, speed, share)

    def facet_flux(self, rho, dt, total=None, facets=slice(None), predicted=None, source=None):
        """The mass each facet (of `facets`) carries f2t[0] -> f2t[1] in the step of rho by dt: the fluxes of rho~
        with the speed of t^n (it solves the step again, as ImplicitUpwindTransport.facet_flux, unless given
        rho~ as `predicted`)."""
        rho_t = self.step(rho, dt, total, source).rho if predicted is None else predicted
        return super().facet_flux(rho_t, dt, rho if total is None else total, facets)


class ImplicitGodunovTransport(ImplicitLWRTransport):
    """``scheme.transport = "implicit-godunov"``: the explicit LWR fluxes made implicit only where the step needs it.

    Rates: the rates of the explicit scheme's flux frozen at t^n. Across a facet from K to L population i carries

        q_e a_e y_i,K,    a_e = F(rho^n_K, rho^n_L) / rho^n_K,

    F the flux of the explicit LWR scheme (lwr.py: Godunov's min(D(rho_K), S(rho_L)) for a unimodal g = r f(r),
    rho_K f(rho_L) otherwise) of the total density, a_e its limit f(0) at rho^n_K = 0 (0 when S(rho^n_L) = 0).

    Density carried: y_K = omega_K rho~_K + (1 - omega_K) rho^n_K, omega_K = max(0, 1 - |K| / (tau out_K)), out_K
    the sum of the rates q_e a_e leaving K: explicit (y = rho^n, the explicit scheme's flux) in every cell whose
    CFL-1 step the step does not exceed, implicit only as much as keeps the explicit part's coefficient
    |K| / tau - (1 - omega_K) out_K >= 0 (a cell-wise theta scheme, as the mixed explicit implicit schemes of
    small cells, May, Berger 2017, J. Sci. Comput.; in one dimension its numerical diffusion is
    |1 - c_K| |v| h / 2 at the cell's Courant number c_K, against (1 + c_K) |v| h / 2 for backward Euler).

    The system (solve) has the pattern of ImplicitLWRTransport's with the rates omega_K q_e a_e >= 0 and a
    right-hand side >= 0: an M-matrix, so rho~ >= 0 and each population's mass is kept at any step; the same order
    of the flow and the same caps in the solve (capped.py). As tau -> 0 (omega = 0 once tau is within every cell's
    CFL-1 step) the step is the explicit scheme's, but for a source's arrivals, which enter the solve (inflow.py).
    With several populations a_e is the same for all (the total's) and omega_K is each one's own. The paper's model
    (f = 1) takes it too: the upwind scheme, implicit only in the cells whose CFL-1 step the step exceeds."""

    every_law = True

    def speeds(self, rho, total=None) -> np.ndarray:
        """The rate of each flow, q_e F(rho^n_K, rho^n_L) / rho^n_K (of the total density with several
        populations)."""
        if not self.godunov:
            return super().speeds(rho, total)
        seen = np.append(rho if total is None else total, 0.0)
        sender = seen[self.sender]
        supply = law_at(self.law.supply, seen, self.receiver)
        flux = np.minimum(law_at(self.law.demand, seen, self.sender), supply)
        limit = np.where(supply > 0, self.law(np.zeros(1)), 0.0)   # the rate of an empty sender
        return np.divide(flux, sender, out=limit, where=sender > 0) * self.rate

    def share(self, dt, speed) -> np.ndarray:
        """omega_K = max(0, 1 - |K| / (tau out_K)): 0 where the step is within the cell's CFL-1 step."""
        out = np.bincount(self.sender, speed, self.domain.ncells)
        with np.errstate(divide="ignore"):
            return np.maximum(1.0 - self.domain.area / (dt * out), 0.0)

    def facet_flux(self, rho, dt, total=None, facets=slice(None), predicted=None, source=None):
        """The mass each facet (of `facets`) carries f2t[0] -> f2t[1] in the step of rho by dt: the frozen rates
        times the density carried (it solves the step again unless given rho~ as `predicted`)."""
        speed = self.speeds(rho, total)
        share = self.share(dt, speed)
        rho_t = self.solve(rho, dt, speed, share, source) if predicted is None else predicted
        which, position, n, inverse = self.across(facets)
        flux = speed[which] * carried(rho, rho_t, share)[self.sender[which]]
        return dt * np.bincount(position, self.flow_sign[which] * flux, n)[inverse]


def carried(rho, rho_t, share) -> np.ndarray:
    """The density the fluxes out of each cell carry: omega rho~ + (1 - omega) rho."""
    return share * rho_t + (1.0 - share) * rho
