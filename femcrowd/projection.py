"""Correction step: projection of rho~ onto {rho <= 1} (design note, sec. 2, step 2).

Find phi = tau p on the cells such that

    w = M_L (1 - rho~) + A phi >= 0,   phi >= 0,   phi . w = 0,

with A the two-point Laplacian (an M-matrix, exits Dirichlet, walls Neumann)
and M_L the cell areas; then |K| rho_K = |K| rho~_K - (A phi)_K, i.e.
rho = 1 - w / |K|. The linear complementarity problem is solved exactly by
primal-dual active-set iterations (Hintermueller, Ito, Kunisch 2003): on the
saturated set S solve A_SS phi_S = -b_S, set phi = 0 elsewhere, then
S <- {phi > 0} U {w < 0}; for an M-matrix this terminates in finitely many
steps. S is warm-started from the previous step, so 1-3 iterations suffice.
Only rows of S and their neighbours are touched; when no cell exceeds 1 the
solution is phi = 0 and nothing is solved.
"""

import numpy as np
import pyamg
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu


class ProjectionError(RuntimeError):
    """The active-set iteration did not terminate (it always does for an M-matrix)."""


class Projection:
    """Exact LCP projection with warm-started active sets."""

    def __init__(self, domain, direct_max=50_000, tol=1e-12, max_iterations=100):
        self.A = domain.laplacian()
        self.area = domain.area
        self.has_exit = np.bincount(domain.f2t[0][domain.exit], minlength=domain.ncells) > 0
        self.direct_max = direct_max
        self.tol = tol
        self.max_iterations = max_iterations
        self.active = np.zeros(domain.ncells, bool)

    def __call__(self, rho_tilde):
        """Return (rho, phi, info) for one correction step."""
        b = self.area * (1.0 - rho_tilde)
        phi = np.zeros_like(b)
        over = b < 0
        if not over.any():
            self.active[:] = False
            return rho_tilde.copy(), phi, {"iterations": 0, "linear_residual": 0.0, "unknowns": 0}
        active = over | self.active
        residual = 0.0
        for iteration in range(1, self.max_iterations + 1):
            idx = np.flatnonzero(active)
            rows = self.A[idx]
            phi[:] = 0.0
            phi[idx], res = self._solve(rows, idx, active, -b[idx])
            residual = max(residual, res)
            # w = b + A phi; A is symmetric, so A phi = rows^T phi_S touches only S and its neighbours
            w = b + rows.T @ phi[idx]
            new = np.where(active, phi > 0, w < -self.tol * self.area)
            if np.array_equal(new, active):
                break
            active = new
        else:
            raise ProjectionError(f"active-set iterations did not terminate in {self.max_iterations}")
        self.active = active
        rho = rho_tilde - (rows.T @ phi[idx]) / self.area
        return rho, phi, {"iterations": iteration, "linear_residual": residual, "unknowns": len(idx)}

    def _solve(self, rows, idx, active, rhs):
        """Solve A_SS phi_S = rhs; returns (phi_S, relative residual).

        A connected component of S with no exit facet and no neighbour outside S
        is a closed, fully saturated room: A is singular there (pure Neumann) and
        the solution is fixed up to a constant. We pin one cell of each such
        component (phi = 0), solve, then shift the component so that min phi = 0
        (the gauge of the design note); the incompatibility of the data, pure
        round-off since the mass fits, lands in the pinned cell.
        """
        A_SS = rows[:, idx]
        coupled = self.has_exit[idx] | ((abs(rows) @ (~active).astype(float)) > 0)
        ncomp, label = connected_components(A_SS, directed=False)
        floating = np.bincount(label, coupled, ncomp) == 0
        keep = np.ones(len(idx), bool)
        if floating.any():
            pinned = np.unique(label[floating[label]], return_index=True)[1]
            keep[pinned] = False
        K = A_SS[keep][:, keep] if not keep.all() else A_SS
        x = np.zeros(len(idx))
        if K.shape[0] > 0:
            x[keep] = self._linear_solve(K.tocsr(), rhs[keep])
        if floating.any():
            lowest = np.full(ncomp, np.inf)
            np.minimum.at(lowest, label, x)
            x -= np.where(floating[label], lowest[label], 0.0)
        r = A_SS @ x - rhs
        scale = np.linalg.norm(rhs[keep]) or 1.0
        return x, float(np.linalg.norm(r[keep]) / scale)

    def _linear_solve(self, K, rhs):
        """Sparse direct for small systems, Ruge-Stuben AMG + CG for large ones."""
        if K.shape[0] <= self.direct_max:
            return splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(rhs)
        ml = pyamg.ruge_stuben_solver(K)
        return ml.solve(rhs, tol=self.tol, accel="cg", maxiter=500)


def velocity_correction(domain, p):
    """-grad p per cell, reconstructed from the two-point fluxes G_e = T_e (p_K - p_L).

    For the lowest-order Raviart-Thomas field with facet fluxes G_e, the cell mean
    is (1/|K|) sum_e G_e (m_e - g_K) (m_e facet midpoint, g_K centroid).
    """
    k0, k1 = domain.f2t
    inner = domain.interior
    p_far = np.where(inner, p[np.where(inner, k1, 0)], 0.0)
    G = domain.transmissibility * (p[k0] - p_far)
    out = np.zeros((domain.ncells, 2))
    for c in range(2):
        out[:, c] = np.bincount(k0, G * (domain.midpoint[:, c] - domain.centroid[k0, c]), domain.ncells)
        out[:, c] -= np.bincount(k1[inner], G[inner] * (domain.midpoint[inner, c]
                                                        - domain.centroid[k1[inner], c]), domain.ncells)
    return out / domain.area[:, None]
