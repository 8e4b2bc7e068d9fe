"""Prediction step: order-0 upwind DG (finite volume) transport by the desired velocity.

    |K| (rho~_K - rho_K) / tau = - sum_{e in K} |e| (a_e^+ rho_K - a_e^- rho_L)

with a_e = U . n_K on the facet, a^+ = max(a, 0), a^- = max(-a, 0). Walls carry no
flux; exits carry only outflow, which is the evacuated mass (design note, sec. 2,
step 1). The flux balance is stored as one sparse matrix F (mass rate = F rho),
built once for a steady U, so a step is one mat-vec.
"""

import numpy as np
import scipy.sparse as sp


class UpwindTransport:
    """Upwind flux operator for given normal velocities on the facets."""

    def __init__(self, domain, normal_velocity):
        self.domain = domain
        a = np.where(domain.wall, 0.0, normal_velocity) * domain.length  # |e| U.n, oriented k0 -> k1
        k0, k1 = domain.f2t
        inner = domain.interior
        out0 = np.maximum(a, 0.0)           # k0 -> k1 (or out through an exit), carries rho_k0
        out1 = np.maximum(-a, 0.0) * inner   # k1 -> k0, carries rho_k1 (exits give no inflow)
        i, j = k0[inner], k1[inner]
        rows = np.concatenate([k0, j, j, i])
        cols = np.concatenate([k0, i, j, j])
        vals = np.concatenate([-out0, out0[inner], -out1[inner], out1[inner]])
        n = domain.ncells
        self.flux = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
        self.exit_rate = sp.csr_matrix(
            (out0[domain.exit], (np.zeros(np.count_nonzero(domain.exit), int), k0[domain.exit])),
            shape=(1, n))
        outflow = np.bincount(k0, out0, n) + np.bincount(k1[inner], out1[inner], n)
        with np.errstate(divide="ignore"):
            self.max_dt = float(np.min(domain.area / outflow))  # inf when nothing moves

    def step(self, rho, dt):
        """rho~ and the mass that left through the exits during dt.

        For dt <= max_dt (CFL <= 1) every coefficient of the update is >= 0, so
        rho~ >= 0; the clip only removes round-off of order 1e-17 at CFL = 1.
        """
        rho_t = rho + (dt / self.domain.area) * (self.flux @ rho)
        np.maximum(rho_t, 0.0, out=rho_t)
        return rho_t, dt * float((self.exit_rate @ rho)[0])
