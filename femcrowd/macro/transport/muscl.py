"""Higher-order prediction: limited linear reconstruction (Barth, Jespersen 1989) with the upwind fluxes,
SSP-RK2 (Shu, Osher 1988) or one Euler stage (anti-diffusive, in the spirit of Despres, Lagoutiere 2001)."""

import numpy as np
import scipy.sparse as sp

from .upwind import Prediction, UpwindTransport


class Reconstruction:
    """Limited linear reconstruction (Barth, Jespersen 1989) of a cell field on the facets of every cell, for a
    transport with outflow rates q_{K,e}^+ (out0, out1 of UpwindTransport, |e| (U.n)^+ across each facet).

    Per cell a least-squares gradient g_K from the face neighbours' centroids, limited by
    Barth-Jespersen (facet values rho_K + phi_K g_K . (m_e - c_K) stay within the min/max
    of K and its neighbours, hence >= 0), then scaled further so that the outflow of a
    forward-Euler stage cannot exceed the cell's mass:

        dt sum_e q_{K,e}^+ (rho_K + phi_K delta_{K,e}) <= |K| rho_K,

    which holds for phi_K = 0 whenever dt <= |K| / sum_e q_{K,e}^+ (the upwind CFL limit). A flux that carries
    at most q_{K,e}^+ times the sender's facet value (the upwind flux, the LWR fluxes: lwr.py) keeps rho >= 0.
    """

    def __init__(self, domain, out0, out1):
        self.domain = domain
        k0, k1 = domain.f2t
        inner = domain.interior
        i, j = k0[inner], k1[inner]
        n = domain.ncells
        d = domain.centroid[j] - domain.centroid[i]
        m = [np.bincount(i, d[:, a] * d[:, b], n) + np.bincount(j, d[:, a] * d[:, b], n)
             for a, b in ((0, 0), (0, 1), (1, 1))]
        det = m[0] * m[2] - m[1] ** 2
        ok = det > 1e-10 * (m[0] + m[2]) ** 2        # at least two independent neighbours
        det = np.where(ok, det, 1.0)
        inv = np.stack([np.stack([m[2], -m[1]], 1), np.stack([-m[1], m[0]], 1)], 1) * (ok / det)[:, None, None]
        wi, wj = np.einsum("nab,nb->na", inv[i], d), np.einsum("nab,nb->na", inv[j], d)
        rows, cols = np.concatenate([i, i, j, j]), np.concatenate([j, i, j, i])
        self.gradient = [sp.csr_matrix((np.concatenate([wi[:, a], -wi[:, a], wj[:, a], -wj[:, a]]),
                                        (rows, cols)), shape=(n, n)) for a in (0, 1)]
        t2f = domain.mesh.t2f                         # (3, n): the facets of each cell
        cells = np.arange(n)
        self.neighbour = np.where(inner[t2f], k0[t2f] + k1[t2f] - cells, cells)
        self.offset = domain.midpoint[t2f] - domain.centroid[None]    # (3, n, 2): m_e - c_K
        own = k0[t2f] == cells                        # is K the f2t[0] side of its facet?
        self.outflow = np.where(own, out0[t2f], out1[t2f])   # q_{K,e}^+ (3, n)
        self.total_outflow = self.outflow.sum(0)
        # flat (3 n) positions of the f2t[0] and f2t[1] cells' values on each facet
        nf = len(domain.length)
        self.pos0, self.pos1 = np.zeros(nf, int), np.zeros(nf, int)
        flat = np.arange(3 * n).reshape(3, n)
        self.pos0[t2f[own]] = flat[own]
        self.pos1[t2f[~own]] = flat[~own]

    def __call__(self, rho, dt):
        """Limited reconstructed values of every cell on its 3 facets, shape (3, n)."""
        gx, gy = self.gradient[0] @ rho, self.gradient[1] @ rho
        delta = self.offset[..., 0] * gx
        delta += self.offset[..., 1] * gy
        delta += 0.0                                  # -0.0 -> +0.0, so that x / delta has the sign of x
        near = rho[self.neighbour]
        high = np.maximum(near.max(0), rho) - rho     # >= 0
        low = np.minimum(near.min(0), rho) - rho      # <= 0
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(delta >= 0, high, low) / delta   # >= 0; 0/0 = nan is skipped by fmin
            phi = np.fmin(np.fmin.reduce(ratio, axis=0), 1.0)  # Barth-Jespersen
            spill = np.einsum("fn,fn->n", self.outflow, delta)
            room = np.maximum(rho * (self.domain.area / dt - self.total_outflow), 0.0) / spill
        phi = np.where(spill > 0, np.minimum(phi, room), phi)   # positivity of the stage
        return rho + phi * delta


class MUSCLTransport(UpwindTransport):
    """``[scheme] transport = "muscl"``: linear reconstruction + SSP-RK2, the same upwind fluxes.

    Each stage is the upwind flux balance with the limited facet values of ``Reconstruction``;
    SSP-RK2 (Heun) averages two stages: rho~ = (rho + E(E(rho))) / 2. Hence rho~ >= 0 at the same
    dt as order 0, mass is conservative (one flux per facet) and the evacuated mass is the mean of
    the stages'. With a speed law the same stages carry Godunov's flux (muscl_lwr.py).

    """

    #: rho~ >= 0 holds up to max_dt; the local extremum diminishing property of limited
    #: reconstructions with Euler stages needs half of it (docs/convergence.md)
    max_cfl = 0.5
    stages = 2

    def __init__(self, domain, exits, normal_velocity, potential=None):
        super().__init__(domain, exits, normal_velocity)
        self.reconstruction = Reconstruction(domain, self.out0, self.out1)
        k0, k1 = domain.f2t
        inner = domain.interior
        n, nf = domain.ncells, len(domain.length)
        # mass rate per cell = divergence @ (net flux k0 -> k1 per facet)
        f = np.arange(nf)
        self.divergence = sp.csr_matrix((np.concatenate([-np.ones(nf), np.ones(np.count_nonzero(inner))]),
                                         (np.concatenate([k0, k1[inner]]), np.concatenate([f, f[inner]]))),
                                        shape=(n, nf))
        ex = np.flatnonzero(exits.exit)
        self.exit_flux = sp.csr_matrix((self.out0[ex], (exits.group[ex], ex)), shape=(len(exits.names), nf))

    def _net(self, rho, dt):
        """The mass rate of each facet k0 -> k1 (or out of an exit) with the limited facet values, and the
        values of the f2t[0] cells."""
        values = self.reconstruction(rho, dt).ravel()
        f0, f1 = values[self.reconstruction.pos0], values[self.reconstruction.pos1]
        return self.out0 * f0 - self.out1 * f1, f0

    def _euler(self, rho, dt) -> Prediction:
        """One forward-Euler stage with the limited facet values."""
        net, f0 = self._net(rho, dt)
        new = rho + (dt / self.domain.area) * (self.divergence @ net)
        np.maximum(new, 0.0, out=new)
        return Prediction(new, dt * (self.exit_flux @ f0), dt * net[self.capped])

    def facet_flux(self, rho: np.ndarray, dt: float, facets=slice(None)) -> np.ndarray:
        """The mass each facet (of `facets`) carries in the step of rho by dt (the mean of the stages' fluxes),
        for measurement lines: it repeats the stages, so step() keeps its cost when nobody measures."""
        net = self._net(rho, dt)[0]
        if self.stages == 1:
            return dt * net[facets]
        return 0.5 * dt * (net + self._net(self._euler(rho, dt)[0], dt)[0])[facets]

    def step(self, rho: np.ndarray, dt: float) -> Prediction:
        """rho~ (SSP-RK2, or one Euler stage), the mass that left through each exit during dt and the net
        mass through the capped door facets (the mean of the stages')."""
        one = self._euler(rho, dt)
        if self.stages == 1:
            return one
        two = self._euler(one.rho, dt)
        return Prediction(0.5 * (rho + two.rho), 0.5 * (one.outflow + two.outflow), 0.5 * (one.through + two.through))


class CompressiveTransport(MUSCLTransport):
    """``[scheme] transport = "compressive"``: the same limited facet values, one forward-Euler
    stage, rho~ = E(rho). Anti-diffusive, in the spirit of Despres-Lagoutiere: jumps stay 1-2
    cells wide for all time (the crowd's free boundary stays sharp), but smooth bumps are
    flattened into plateaus. Same bounds, mass conservation and CFL limit."""

    stages = 1
