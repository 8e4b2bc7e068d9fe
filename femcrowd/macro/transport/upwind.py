"""Prediction step: order-0 upwind DG (finite volume) transport by the desired velocity
(docs/model.md, "The catching-up scheme").

    |K| (rho~_K - rho_K) / tau = - sum_{e in K} |e| (a_{K,e}^+ rho_K - a_{L,e}^- rho_L)

with a_{K,e} = U_K . n_K the normal velocity of facet e seen from cell K, L the
cell across e, a^+ = max(a, 0), a^- = max(-a, 0). For a continuous U both cells
see the same a_e (U at the facet midpoint) and this is the classical upwind
flux. For a cellwise U (type "exits") it is the flux-splitting upwind flux:
every cell carries its own mass out with its own velocity. It is conservative
(one flux per facet) and monotone, and unlike a mean of the two velocities it
never lets a neighbour that moves away push mass back into a cell (which
left cells stuck in the fan of directions around a door post). Walls (and
closed exits) carry no flux; open exits carry only outflow, which is the
evacuated mass. The flux balance is stored as one sparse matrix F (mass
rate = F rho), built once per steady U and set of open exits, so a step is
one mat-vec.
"""

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp


class Prediction(NamedTuple):
    """A transport step: rho~, the mass that left through each exit (over exits.names), and the net mass
    carried f2t[0] -> f2t[1] across each capped door facet (exits.caps.facets; empty without capacities)."""

    rho: np.ndarray
    outflow: np.ndarray
    through: np.ndarray


class UpwindTransport:
    """Upwind flux operator for given normal velocities on the facets and a set of open exits."""

    max_cfl = 1.0   # largest time.cfl (fraction of max_dt) the scheme accepts

    def __init__(self, domain, exits, normal_velocity, potential=None):
        """normal_velocity: (2, F) U.n on each facet seen from f2t[0] and from f2t[1], n oriented k0 -> k1;
        potential: unused by the explicit schemes."""
        self.domain = domain
        a0, a1 = np.where(exits.wall, 0.0, normal_velocity) * domain.length
        k0, k1 = domain.f2t
        inner = domain.interior
        out0 = np.maximum(a0, 0.0)           # k0 -> k1 (or out through an exit), carries rho_k0
        out1 = np.maximum(-a1, 0.0) * inner  # k1 -> k0, carries rho_k1 (exits give no inflow)
        i, j = k0[inner], k1[inner]
        ahead, back = out0[inner] > 0, out1[inner] > 0  # upwind: mostly one direction per facet
        n = domain.ncells
        cells = np.arange(n)
        rows = np.concatenate([cells, k0, j, j[ahead], i[back]])
        cols = np.concatenate([cells, k0, j, i[ahead], j[back]])
        vals = np.concatenate([np.zeros(n), -out0, -out1[inner], out0[inner][ahead], out1[inner][back]])
        # every diagonal entry is stored (the update matrix sets it), no zero off the diagonal
        self.flux = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
        self._diagonal = np.flatnonzero(self.flux.indices == np.repeat(cells, np.diff(self.flux.indptr)))
        self.exit_rate = exits.outflow_matrix(out0)  # outflow rate per exit
        self.out0, self.out1 = out0, out1
        self.capped = exits.caps.facets if exits.caps is not None else np.zeros(0, np.intp)
        self._update, self._update_dt = None, None  # I + dt diag(1/|K|) F for the usual dt (see step)
        outflow = np.bincount(k0, out0, n) + np.bincount(k1[inner], out1[inner], n)
        with np.errstate(divide="ignore"):
            self.cell_dt = domain.area / outflow   # the CFL-1 step of each cell, inf where nothing leaves it
        self.max_dt = float(np.min(self.cell_dt))  # inf when nothing moves
        self._quantiles = {}

    def courant_dt(self, quantile: float) -> float:
        """The ``quantile`` of the cells' CFL-1 steps |K| / (outflow rate of K) over the cells that move
        (``time.cfl_quantile``, docs/model.md "Steps by accuracy"); 0: max_dt, the smallest."""
        if quantile == 0:
            return self.max_dt
        if quantile not in self._quantiles:
            moving = self.cell_dt[np.isfinite(self.cell_dt)]
            self._quantiles[quantile] = float(np.quantile(moving, quantile)) if len(moving) else np.inf
        return self._quantiles[quantile]

    def step(self, rho: np.ndarray, dt: float) -> Prediction:
        """rho~, the mass that left through each exit during dt (array over exits.names) and the net mass
        through the capped door facets (the cap itself is the doors', mesh/capacity.py).

        From its second step on (a time-dependent U makes a new transport every
        step), a step is one mat-vec with the update matrix B (see update_matrix),
        built for the largest dt seen; a shorter step (cut at an output time) is the
        convex combination rho + (dt / dt_B) (B rho - rho), without rebuilding B.
        B >= 0 entrywise, so rho >= 0 gives rho~ >= 0 exactly, in floating point too
        (sums and products of non-negative numbers; the convex combination rounds
        monotonically between 0 and the larger of rho, B rho). The first step,
        rho + dt diag(1/|K|) F rho, clips the round-off of order 1e-17 at CFL = 1.
        """
        if dt > self.max_dt:
            raise ValueError(f"dt = {dt:.6g} exceeds the CFL limit {self.max_dt:.6g} of the upwind transport")
        if self._update_dt is None:
            self._update_dt = 0.0
            rho_t = rho + (dt / self.domain.area) * (self.flux @ rho)
            np.maximum(rho_t, 0.0, out=rho_t)
        else:
            if dt > self._update_dt:
                self._update = self.update_matrix(dt)
                self._update_dt = dt
            rho_t = self._update @ rho
            if dt < self._update_dt:
                rho_t -= rho
                rho_t *= dt / self._update_dt
                rho_t += rho
        return Prediction(rho_t, dt * (self.exit_rate @ rho), self._carried(rho, dt, self.capped))

    def facet_flux(self, rho: np.ndarray, dt: float, facets=slice(None)) -> np.ndarray:
        """The mass each facet (of `facets`) carries f2t[0] -> f2t[1] (out of the domain through an exit) in the
        step of rho by dt that step() makes (for measurement lines; step() does not compute it)."""
        return self._carried(rho, dt, facets)

    def _carried(self, rho, dt, facets=slice(None)):
        """The upwind fluxes of rho across `facets` over dt, f2t[0] -> f2t[1]."""
        k0, k1 = self.domain.f2t[0][facets], self.domain.f2t[1][facets]
        return dt * (self.out0[facets] * rho[k0] - self.out1[facets] * rho[np.maximum(k1, 0)])

    def update_matrix(self, dt):
        """B = I + dt diag(1/|K|) F (CSR), rho~ = B rho, with its diagonal clipped at 0.

        For dt <= max_dt the diagonal 1 - dt q_K / |K| (q_K the outflow rate of K) is >= 0
        but for round-off of order 1e-16 at CFL = 1, and the other entries are >= 0; the clip
        moves that round-off into the matrix, once, instead of clipping rho~ every step.
        """
        update = self.flux.copy()
        update.data *= np.repeat(dt / self.domain.area, np.diff(update.indptr))
        update.data[self._diagonal] = np.maximum(update.data[self._diagonal] + 1.0, 0.0)
        return update
