"""Prediction with a density-dependent speed U = f(rho) U0: the LWR flux across each facet (Maury,
Roudneff-Chupin, Santambrogio, Venel 2011, section on extensions; docs/extensions.md).

The facet rates q_e = |e| (U0.n)^+ of the upwind scheme (upwind.py, flux splitting for a cellwise
U0) carry, from the sender K to the receiver L (the empty outside across an exit),

    Godunov (g = r f(r) unimodal):  F_e = q_e min(D(rho_K), S(rho_L))   (Lebacque 1996 demand/supply)
    otherwise:                      F_e = q_e rho_K f(rho_L)             (upwind density, downstream speed)

where rho is the total density (the crowd people see) and a population i sends its share
rho_i,K / rho_K of the sender's flux. Both fluxes use the density downstream, as the paper asks.
For a unimodal g the demand/supply flux is Godunov's exact Riemann flux (the least diffusive monotone
flux); for a g with several humps it is not consistent (min(D(r), S(r)) > g(r) in a valley), while
rho_K f(rho_L) is monotone and consistent for every non-increasing f.

Bounds, with out_K, in_K the rates q_e leaving and entering K and L_f the law's constant (lipschitz):
each flux is at most q_e rho_i,K (D(r) <= r, f <= 1), so rho_i >= 0 when dt out_K <= |K|; the
flux into K is at most q_e S(rho_K) <= q_e L_f (1 - rho_K) when f(1) = 0, so rho <= 1 when
dt in_K L_f <= |K| (for several populations in_K takes the largest rate of the populations on each
facet): with f(1) = 0 the density never exceeds 1 and the projection is never needed.
"""

import numpy as np

from .upwind import Prediction, UpwindTransport


class LWRTransport(UpwindTransport):
    """The LWR fluxes of one population with speed law ``law`` (femcrowd.macro.speed_law.SpeedLaw)."""

    #: whether a population without a speed law takes this scheme too (with f = 1), not the transport's own
    every_law = False
    #: whether the step keeps the total density <= 1 when f(1) = 0 for every population (the projection skipped)
    bounded = True
    #: whether the populations step together (each stage's law seeing the stage's total: muscl_lwr.py)
    together = False

    def __init__(self, domain, exits, normal_velocity, law):
        super().__init__(domain, exits, normal_velocity)
        self.law = law
        self.godunov = law.unimodal
        # for the downstream-speed flux the bound needs the Lipschitz constant of f, not of g
        self.steepness = law.lipschitz if self.godunov else law.slope
        k0, k1 = domain.f2t
        n = domain.ncells
        inner = domain.interior
        self.outside = n                        # index of the empty outside (behind an exit)
        f0, f1 = np.flatnonzero(self.out0 > 0), np.flatnonzero(self.out1 > 0)
        # senders and receivers of the flows k0 -> k1 (f0) and k1 -> k0 (f1), the outside for exits
        self.sender = np.concatenate([k0[f0], k1[f1]])
        self.receiver = np.concatenate([np.where(inner[f0], k1[f0], n), k0[f1]])
        self.rate = np.concatenate([self.out0[f0], self.out1[f1]])
        self.flow_facet = np.concatenate([f0, f1])
        self.flow_sign = np.concatenate([np.ones(len(f0)), -np.ones(len(f1))])   # along f2t[0] -> f2t[1]
        # where each flow reads the density its law sees on its two sides: the cells (muscl_lwr.py: their facet values)
        self.sending, self.receiving = self.sender, self.receiver
        leaving = self.receiver == n
        self.exit_flows = np.flatnonzero(leaving)
        self.exit_of_flow = exits.group[f0[leaving[: len(f0)]]]
        self.n_exits = len(exits.names)
        self.out_rate = np.bincount(self.sender, self.rate, n)
        # the flows across the capped door facets: their position among them, the sign along f2t[0] -> f2t[1]
        position = np.full(len(self.out0), -1)
        position[self.capped] = np.arange(len(self.capped))
        self.capped_flows = np.flatnonzero(position[self.flow_facet] >= 0)
        self.capped_position = position[self.flow_facet[self.capped_flows]]
        self.max_dt = joint_max_dt(domain, [self])
        self._flows_across = {}   # per set of facets (measurement lines): their flows and where they go

    def flows(self, rho, total=None, which=slice(None)):
        """The mass rate of this population along each flow (of `which`, default all; sender -> receiver);
        ``total``: the density of all populations, which the speed law sees (default: rho, one population).
        rho and total are read at self.sending and self.receiving (index len(total): the empty outside)."""
        total = rho if total is None else total
        seen = np.append(total, 0.0)   # the outside is empty
        sender, receiver = self.sending[which], self.receiving[which]
        if self.godunov:
            flux = np.minimum(law_at(self.law.demand, seen, sender), law_at(self.law.supply, seen, receiver))
        else:
            flux = seen[sender] * law_at(self.law, seen, receiver)
        if total is not rho:   # this population's share of the sender's flux
            with np.errstate(invalid="ignore", divide="ignore"):
                flux *= np.where(total[sender] > 0, rho[sender] / total[sender], 0.0)
        return flux * self.rate[which]

    def step(self, rho, dt, total=None) -> Prediction:
        """rho~ of this population, the mass that left through each exit during dt and the net mass through
        the capped door facets (capped by the doors: min(D, c, S), mesh/capacity.py)."""
        if dt > self.max_dt * (1 + 1e-12):
            raise ValueError(f"dt = {dt:.6g} exceeds the CFL limit {self.max_dt:.6g} of the LWR transport")
        return self.balance(rho, self.flows(rho, total), dt)

    def balance(self, rho, flux, dt) -> Prediction:
        """The forward-Euler step of rho by the mass rates ``flux`` of the flows over dt, with what left through
        each exit and the net mass through the capped door facets."""
        n = len(rho)
        net = np.bincount(self.receiver, flux, n + 1)[:n] - np.bincount(self.sender, flux, n)
        rho_t = rho + (dt / self.domain.area) * net
        np.maximum(rho_t, 0.0, out=rho_t)   # round-off of order 1e-17 at the CFL limit
        evacuated = dt * np.bincount(self.exit_of_flow, flux[self.exit_flows], self.n_exits)
        through = dt * np.bincount(self.capped_position, self.flow_sign[self.capped_flows] * flux[self.capped_flows],
                                   len(self.capped))
        return Prediction(rho_t, evacuated, through)

    def facet_flux(self, rho, dt, total=None, facets=slice(None)):
        """The mass each facet (of `facets`) carries f2t[0] -> f2t[1] in the step of rho by dt (measurement lines);
        only the flows across these facets are evaluated."""
        which, position, n, inverse = self.across(facets)
        moved = np.bincount(position, self.flow_sign[which] * self.flows(rho, total, which), n)
        return dt * moved[inverse]

    def across(self, facets):
        """The flows across `facets` (which), the position of each one's facet among the n distinct facets, and
        the distinct facet of each of `facets` (inverse); kept per set of facets."""
        every = np.arange(len(self.out0))[facets]
        key = every.tobytes()
        if key not in self._flows_across:
            unique, inverse = np.unique(every, return_inverse=True)
            position = np.full(len(self.out0), -1)
            position[unique] = np.arange(len(unique))
            which = np.flatnonzero(position[self.flow_facet] >= 0)
            self._flows_across[key] = which, position[self.flow_facet[which]], len(unique), inverse
        return self._flows_across[key]


def law_at(f, values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """f(values[index]) for a law f that acts elementwise (f, D, S): taken of the values and gathered when the
    index is the longer (every flow of a mesh: more flows than cells), the same numbers, fewer evaluations."""
    return f(values)[index] if len(index) > len(values) else f(values[index])


def joint_max_dt(domain, schemes) -> float:
    """The largest step that keeps every population >= 0 and, when f(1) = 0 for all, their sum <= 1: the
    minimum over the cells of |K| / max(max_i max(1, L_i) out_i,K, sum over K's facets of max_i L_i q_i,e)."""
    n = domain.ncells
    out = np.max([max(1.0, s.steepness) * s.out_rate for s in schemes], axis=0)
    # largest entering rate per (receiver, facet) pair over the populations
    entering = np.zeros(n)
    if schemes:
        k0, k1 = domain.f2t
        inner = domain.interior
        into_k1 = np.max([s.steepness * np.where(inner, s.out0, 0.0) for s in schemes], axis=0)
        into_k0 = np.max([s.steepness * s.out1 for s in schemes], axis=0)
        entering = np.bincount(k1[inner], into_k1[inner], n) + np.bincount(k0, into_k0, n)
    with np.errstate(divide="ignore"):
        return float(np.min(domain.area / np.maximum(out, entering)))
