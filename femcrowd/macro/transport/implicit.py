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

    def step(self, rho: np.ndarray, dt: float) -> Prediction:
        """rho~, the mass that left through each exit during dt and the net mass through the capped door
        facets (at the new density)."""
        lu = self._factors.get(dt) or self._factorise(dt)
        if self.order is None:
            rho_t = lu.solve(rho)
        else:
            rho_t = np.empty_like(rho)
            rho_t[self.order] = lu.solve(rho[self.order])
        np.maximum(rho_t, 0.0, out=rho_t)  # the inverse is >= 0: only round-off is clipped
        return Prediction(rho_t, dt * (self.exit_rate @ rho_t), self._carried(rho_t, dt, self.capped))

    def facet_flux(self, rho: np.ndarray, dt: float, facets=slice(None)) -> np.ndarray:
        """The mass each facet (of `facets`) carries in the step of rho by dt: the upwind fluxes of the new density
        rho~ (for measurement lines; it solves the step again, so step() keeps its cost when nobody measures)."""
        return self._carried(self.step(rho, dt).rho, dt, facets)

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
