"""The density people see around them: what Hughes' cost of the route choice counts at doors without a
capacity (``[velocity] route = "congestion"``, :class:`femcrowd.macro.velocity.CongestionVelocity`).

rho_s solves the screened Poisson (Helmholtz filter) problem

    rho_s - l^2 div grad rho_s = rho   in the floor,   no flux across walls and exits,

with the two-point finite-volume Laplacian of the projection (T_e = |e| / d_e across interior facets):
(|K| + l^2 L) rho_s = |K| rho. Its matrix is an M-matrix whose rows sum to |K|, so rho_s keeps the mass of
rho and 0 <= rho_s <= max rho, and rho = 0 gives rho_s = 0 (the free-flow limit of the route choice is the
walking distance, exactly). A person sees the crowd around them, not their cell (people who see the crowd
near them: Carrillo, Martin, Wolfram 2016, M3AS 26, arXiv:1501.07054, "A local version of the Hughes model
for pedestrian flow"). On the mesh it matters too: with the cell densities themselves the cost
jumps from triangle to triangle, the gradients of the potential point into one another, and the
transport's step and the projection's work grow (docs/performance.md, "Route choice").

The filter's kernel in the plane is K_0(r / l) / (2 pi l^2), of second moment 4 l^2; SEEN_LENGTH gives it
the second moment of the uniform circle of radius 1 m whose discs the disc model's route sees
(micro/density.py): 4 l^2 = R^2 / 2.
"""

import numpy as np
import scipy.sparse as sp

from ..linalg.cholmod import Cholesky, lower_pattern

#: l (m): the spread of the uniform circle of radius 1 m, R / sqrt(8)
SEEN_LENGTH = 1.0 / np.sqrt(8.0)


class SeenDensity:
    """rho -> rho_s on the cells of a domain; the matrix is factorised on the first call (once per mesh)."""

    def __init__(self, domain, length: float = SEEN_LENGTH):
        self.domain, self.length = domain, float(length)
        self._factor = None

    def __call__(self, rho: np.ndarray) -> np.ndarray:
        if self._factor is None:
            self._factor = self._factorise()
        area = self.domain.area
        seen = np.array(self._factor.solve(area * rho)).ravel()
        return np.clip(seen, 0.0, rho.max(initial=0.0))   # round-off only: the M-matrix keeps the bounds

    def _factorise(self) -> Cholesky:
        d = self.domain
        inner = d.interior
        k0, k1, T = d.f2t[0][inner], d.f2t[1][inner], self.length**2 * d.transmissibility[inner]
        n = d.ncells
        matrix = sp.coo_matrix((np.concatenate([d.area, T, T, -T, -T]),
                                (np.concatenate([np.arange(n), k0, k1, k0, k1]),
                                 np.concatenate([np.arange(n), k0, k1, k1, k0]))), shape=(n, n))
        rows, cols, values = lower_pattern(matrix.tocsc())
        factor = Cholesky(rows, cols, n)
        factor.factorise(values)
        return factor
