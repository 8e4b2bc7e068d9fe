"""Prediction step: order-0 upwind DG (finite volume) transport by the desired velocity.

    |K| (rho~_K - rho_K) / tau = - sum_{e in K} |e| (a_{K,e}^+ rho_K - a_{L,e}^- rho_L)

with a_{K,e} = U_K . n_K the normal velocity of facet e seen from cell K, L the
cell across e, a^+ = max(a, 0), a^- = max(-a, 0). For a continuous U both cells
see the same a_e (U at the facet midpoint) and this is the classical upwind
flux. For a cellwise U (type "exits") it is the flux-splitting upwind flux:
every cell carries its own mass out with its own velocity. It is conservative
(one flux per facet) and monotone, and unlike a mean of the two velocities it
never lets a neighbour that moves away push mass back into a cell (which
left cells stuck in the fan of directions around a door post). Walls carry no
flux; exits carry only outflow, which is the evacuated mass (design note, sec. 2,
step 1). The flux balance is stored as one sparse matrix F (mass rate = F rho),
built once for a steady U, so a step is one mat-vec.
"""

import numpy as np
import scipy.sparse as sp


class UpwindTransport:
    """Upwind flux operator for given normal velocities on the facets."""

    def __init__(self, domain, normal_velocity):
        """normal_velocity: (2, F) U.n on each facet seen from f2t[0] and from f2t[1], n oriented k0 -> k1."""
        self.domain = domain
        a0, a1 = np.where(domain.wall, 0.0, normal_velocity) * domain.length
        k0, k1 = domain.f2t
        inner = domain.interior
        out0 = np.maximum(a0, 0.0)           # k0 -> k1 (or out through an exit), carries rho_k0
        out1 = np.maximum(-a1, 0.0) * inner  # k1 -> k0, carries rho_k1 (exits give no inflow)
        i, j = k0[inner], k1[inner]
        rows = np.concatenate([k0, j, j, i])
        cols = np.concatenate([k0, i, j, j])
        vals = np.concatenate([-out0, out0[inner], -out1[inner], out1[inner]])
        n = domain.ncells
        self.flux = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
        self.exit_rate = exit_matrix(domain, out0)  # outflow rate per exit group
        outflow = np.bincount(k0, out0, n) + np.bincount(k1[inner], out1[inner], n)
        with np.errstate(divide="ignore"):
            self.max_dt = float(np.min(domain.area / outflow))  # inf when nothing moves

    def step(self, rho, dt):
        """rho~ and the mass that left through each exit group during dt (array, see exit_matrix).

        For dt <= max_dt (CFL <= 1) every coefficient of the update is >= 0, so
        rho~ >= 0; the clip only removes round-off of order 1e-17 at CFL = 1.
        """
        rho_t = rho + (dt / self.domain.area) * (self.flux @ rho)
        np.maximum(rho_t, 0.0, out=rho_t)
        return rho_t, dt * (self.exit_rate @ rho)


def exit_matrix(domain, weights):
    """Sparse (exit groups x cells) matrix: row g sums weights_e * value_K(e) over the exit facets e
    of group g (groups in the order of domain.exit_group; a facet counts once, in its first group)."""
    group = np.full(len(domain.length), -1)
    for g, facets in reversed(list(enumerate(domain.exit_group.values()))):
        group[facets] = g
    e = np.flatnonzero(group >= 0)
    return sp.csr_matrix((weights[e], (group[e], domain.f2t[0][e])),
                         shape=(len(domain.exit_group), domain.ncells))
