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

    max_cfl = 1.0   # largest time.cfl (fraction of max_dt) the scheme accepts

    def __init__(self, domain, normal_velocity):
        """normal_velocity: (2, F) U.n on each facet seen from f2t[0] and from f2t[1], n oriented k0 -> k1."""
        self.domain = domain
        a0, a1 = np.where(domain.wall, 0.0, normal_velocity) * domain.length
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
        self.exit_rate = exit_matrix(domain, out0)  # outflow rate per exit group
        self.out0, self.out1 = out0, out1
        self._update, self._update_dt = None, None  # I + dt diag(1/|K|) F for the usual dt (see step)
        outflow = np.bincount(k0, out0, n) + np.bincount(k1[inner], out1[inner], n)
        with np.errstate(divide="ignore"):
            self.max_dt = float(np.min(domain.area / outflow))  # inf when nothing moves

    def step(self, rho, dt):
        """rho~ and the mass that left through each exit group during dt (array, see exit_matrix).

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
        return rho_t, dt * (self.exit_rate @ rho)

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


def exit_group_of_facets(domain):
    """Exit group index of every facet (-1: not an exit; a facet counts once, in its first group)."""
    group = np.full(len(domain.length), -1)
    for g, facets in reversed(list(enumerate(domain.exit_group.values()))):
        group[facets] = g
    return group


def exit_matrix(domain, weights):
    """Sparse (exit groups x cells) matrix: row g sums weights_e * value_K(e) over the exit facets e
    of group g (groups in the order of domain.exit_group; a facet counts once, in its first group)."""
    group = exit_group_of_facets(domain)
    e = np.flatnonzero(group >= 0)
    return sp.csr_matrix((weights[e], (group[e], domain.f2t[0][e])),
                         shape=(len(domain.exit_group), domain.ncells))


class MUSCLTransport(UpwindTransport):
    """``[scheme] transport = "muscl"``: linear reconstruction + SSP-RK2, the same upwind fluxes.

    Per cell a least-squares gradient g_K from the face neighbours' centroids, limited by
    Barth-Jespersen (facet values rho_K + phi_K g_K . (m_e - c_K) stay within the min/max
    of K and its neighbours, hence >= 0), then scaled further so that the outflow of a
    forward-Euler stage cannot exceed the cell's mass:

        dt sum_e q_{K,e}^+ (rho_K + phi_K delta_{K,e}) <= |K| rho_K,

    which holds for phi_K = 0 whenever dt <= max_dt (the upwind CFL limit). Each stage is
    the upwind flux balance with these facet values; SSP-RK2 (Heun) averages two stages:
    rho~ = (rho + E(E(rho))) / 2. Hence rho~ >= 0 at the same dt as order 0, mass is
    conservative (one flux per facet) and the evacuated mass is the mean of the stages'.

    """

    #: rho~ >= 0 holds up to max_dt; the local extremum diminishing property of limited
    #: reconstructions with Euler stages needs half of it (measured: "compressive" at cfl 1.0
    #: leaves cell-to-cell oscillations on the radial case, refine 4; none at 0.5)
    max_cfl = 0.5
    stages = 2

    def __init__(self, domain, normal_velocity):
        super().__init__(domain, normal_velocity)
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
        self.outflow = np.where(own, self.out0[t2f], self.out1[t2f])   # q_{K,e}^+ (3, n)
        self.total_outflow = self.outflow.sum(0)
        # flat (3 n) positions of the f2t[0] and f2t[1] cells' values on each facet
        nf = len(domain.length)
        self.pos0, self.pos1 = np.zeros(nf, int), np.zeros(nf, int)
        flat = np.arange(3 * n).reshape(3, n)
        self.pos0[t2f[own]] = flat[own]
        self.pos1[t2f[~own]] = flat[~own]
        # mass rate per cell = divergence @ (net flux k0 -> k1 per facet)
        f = np.arange(nf)
        self.divergence = sp.csr_matrix((np.concatenate([-np.ones(nf), np.ones(len(i))]),
                                         (np.concatenate([k0, j]), np.concatenate([f, f[inner]]))), shape=(n, nf))
        group = exit_group_of_facets(domain)
        ex = np.flatnonzero(group >= 0)
        self.exit_flux = sp.csr_matrix((self.out0[ex], (group[ex], ex)), shape=(len(domain.exit_group), nf))

    def _facet_values(self, rho, dt):
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

    def _euler(self, rho, dt):
        """One forward-Euler stage with the limited facet values; (new rho, outflow per exit group)."""
        values = self._facet_values(rho, dt).ravel()
        f0, f1 = values[self.pos0], values[self.pos1]
        net = self.out0 * f0 - self.out1 * f1           # mass rate k0 -> k1 (or out of an exit)
        new = rho + (dt / self.domain.area) * (self.divergence @ net)
        np.maximum(new, 0.0, out=new)
        return new, dt * (self.exit_flux @ f0)

    def step(self, rho, dt):
        """rho~ (SSP-RK2, or one Euler stage) and the mass that left through each exit group during dt."""
        one, out1 = self._euler(rho, dt)
        if self.stages == 1:
            return one, out1
        two, out2 = self._euler(one, dt)
        return 0.5 * (rho + two), 0.5 * (out1 + out2)


class CompressiveTransport(MUSCLTransport):
    """``[scheme] transport = "compressive"``: the same limited facet values, one forward-Euler
    stage, rho~ = E(rho). Anti-diffusive, in the spirit of Despres-Lagoutiere: jumps stay 1-2
    cells wide for all time (the crowd's free boundary stays sharp), but smooth bumps are
    flattened into plateaus. Same bounds, mass conservation and CFL limit."""

    stages = 1
