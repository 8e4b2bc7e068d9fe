"""The actual velocity u = U - grad p per cell, for output: the lowest-order Raviart-Thomas cell mean
of the scheme's own facet fluxes (Raviart, Thomas 1977)."""

import numpy as np
import scipy.sparse as sp


class CellMean:
    """Cell means u_K = (1/|K|) sum_e G_e (m_e - g_K) of the RT0 field with facet fluxes G_e, on the cells
    `cells` (distinct; default all), assembled once: u = A0 G + A1 G1 with G the fluxes k0 -> k1 seen from the
    cells f2t[0] and G1 seen from f2t[1] (they differ for a field that is discontinuous across facets).
    ``facets``: the facets of these cells, the only fluxes it reads."""

    def __init__(self, domain, cells=None):
        cells = np.arange(domain.ncells) if cells is None else np.asarray(cells)
        row = np.full(domain.ncells, -1)
        row[cells] = np.arange(len(cells))
        k0, k1 = domain.f2t
        r0, r1 = row[k0], np.where(k1 >= 0, row[np.maximum(k1, 0)], -1)
        self.facets = np.flatnonzero((r0 >= 0) | (r1 >= 0))
        self.cells = cells
        self.A0, self.A1 = (self._side(domain, r, k, sign) for r, k, sign in ((r0, k0, 1.0), (r1, k1, -1.0)))

    def _side(self, domain, row, cell, sign):
        """The (2 n, F) block of one side: rows x then y of the cells, columns the facets of ``self.facets``."""
        e = np.flatnonzero(row[self.facets] >= 0)
        f = self.facets[e]
        arm = sign * (domain.midpoint[f] - domain.centroid[cell[f]]) / domain.area[cell[f], None]
        n = len(self.cells)
        return sp.csr_array((arm.T.ravel(), (np.concatenate([row[f], row[f] + n]), np.tile(e, 2))),
                            shape=(2 * n, len(self.facets)))

    def __call__(self, G: np.ndarray, G1: np.ndarray | None = None) -> np.ndarray:
        """(n, 2): the means from the fluxes on ``facets``."""
        u = self.A0 @ G + self.A1 @ (G if G1 is None else G1)
        return u.reshape(2, -1).T


def actual_velocity(domain, exits, normal_velocity: np.ndarray, p: np.ndarray, jump: np.ndarray,
                    mean: CellMean) -> np.ndarray:
    """u = U - grad p on the cells of ``mean``, from the facet fluxes |e| U.n (none through walls; normal_velocity
    given on mean.facets) plus the pressure fluxes T_e (p_K - p_L - j_e) (p_L = 0 across an open exit, j_e the
    pressure jump of a capped door facet). Hence u.n = 0 on walls and u = 0 where nothing moves (a closed
    saturated room); U(centroid) - grad p would be O(1) wrong there in the cells along the walls, whose U.n the
    scheme never transports."""
    f = mean.facets
    flux = np.where(exits.wall[f], 0.0, normal_velocity) * domain.length[f] + exits.pressure_flux(p, jump, f)
    return mean(*flux)
