"""The correction of several populations (Maury, Roudneff-Chupin, Santambrogio, Venel 2011, section on
extensions): one constraint on the total density, one pressure, and each population moved by the
common correction, d_t rho_i + div(rho_i (U_i - grad p)) = 0.

The projection of the total rho~ = sum_i rho~_i gives phi = tau p and the mass F_e moved across each
facet, from the cell of larger phi (the sender K) to the other (the receiver, or out through an exit).
Population i takes the share of F_e that it has in the sender *after* the step (an implicit upwind
split): with y_i,K = rho_i,K^{n+1} / rho_K^{n+1},

    |K| rho_i,K^{n+1} = |K| rho~_i,K - sum_{e out of K} F_e y_i,K + sum_{e into K} F_e y_i,L,

i.e. on the senders (|K| rho_K^{n+1} + Out_K) y_i,K - sum_{e into K} F_e y_i,L = |K| rho~_i,K.
Ordered by decreasing phi the matrix is lower triangular (mass flows down phi) with a positive
diagonal and off-diagonal entries <= 0, and its column sums are |K| rho_K^{n+1} > 0: an M-matrix.
Hence y_i >= 0 (forward substitution adds non-negative numbers), sum_i y_i = 1 (y = 1 solves the
sum of the systems, since |K| rho^{n+1} = |K| rho~ - Out + In), and rho_i^{n+1} computed from the
facet fluxes F_e y_i,sender conserves each population to round-off (a negative round-off of order
1e-17 where rho_i,K^{n+1} = 0 is set to 0). An explicit split by the
fractions of rho~ can make a population negative: a saturated cell passes on more mass than it
holds when the pressure pushes a stream through it (tests/macro/test_populations.py shows one).
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve_triangular


def split_correction(domain, exits, flux, rho_tilde: np.ndarray, total: np.ndarray):
    """(rho^{n+1} (populations, cells), pressure outflow (populations, exits)) from the predictions
    rho~ (populations, cells), the PressureFlux of the projection and the corrected total density."""
    rho = rho_tilde.copy()
    evacuated = np.zeros((len(rho_tilde), len(exits.names)))
    # the facets of the cells the correction touches (S and its neighbours): T_e (phi_K - phi_L - j_e) there
    n, touched = domain.ncells, flux.cells
    mark = np.zeros(len(domain.length), bool)
    mark[domain.mesh.t2f[:, touched]] = True
    facets = np.flatnonzero(mark)
    k0, k1 = domain.f2t[0][facets], domain.f2t[1][facets]
    moved = flux.facet_flux(domain, exits, facets)
    # across an exit only outflow: at a door at capacity its flux is 0 up to round-off (1e-20), either sign
    keep = (moved > 0) | ((moved < 0) & (k1 >= 0))
    if not keep.any():
        return rho, evacuated
    facets, k0, k1, moved = facets[keep], k0[keep], k1[keep], moved[keep]
    forward = moved > 0
    sender = np.where(forward, k0, k1)
    receiver = np.where(forward, k1, k0)          # -1 across an exit (only forward: phi = 0 outside)
    mass = np.abs(moved)
    # the senders in order of decreasing phi (lower-triangular system), their positions
    sends = np.zeros(n, bool)
    sends[sender] = True
    cells = np.flatnonzero(sends)
    cells = cells[np.argsort(-flux.phi[cells], kind="stable")]
    position = np.full(n, -1)
    position[cells] = np.arange(len(cells))
    area = domain.area
    diagonal = area[cells] * total[cells] + np.bincount(position[sender], mass, len(cells))
    inside = receiver >= 0
    among = inside & (position[np.maximum(receiver, 0)] >= 0)   # flows between two senders
    # the system scaled by its diagonal, D^-1 B = I - D^-1 N (CSC, lower triangular): forward substitution
    # adds (F_e / D_K) y_L >= 0 to (|K| rho~_i,K) / D_K >= 0
    to, of = position[receiver[among]], position[sender[among]]
    ones = np.arange(len(cells))
    B = sp.csc_matrix((np.concatenate([np.ones(len(cells)), -mass[among] / diagonal[to]]),
                       (np.concatenate([ones, to]), np.concatenate([ones, of]))), shape=(len(cells), len(cells)))
    y = spsolve_triangular(B, (area[cells] * rho_tilde[:, cells] / diagonal).T, lower=True, unit_diagonal=True,
                           overwrite_A=True, overwrite_b=True)
    y = y.reshape(len(cells), -1).T                # (populations, senders)
    moved_i = mass * y[:, position[sender]]        # (populations, flows)
    # the balance of each cell the correction touches, in their compact numbering
    local = np.full(n, -1)
    local[touched] = np.arange(len(touched))
    out_of, into = local[sender], local[receiver[inside]]
    for i in range(len(rho)):
        net = np.bincount(into, moved_i[i, inside], len(touched)) - np.bincount(out_of, moved_i[i], len(touched))
        rho[i, touched] = np.maximum(rho[i, touched] + net / area[touched], 0.0)   # round-off: see above
        evacuated[i] = np.bincount(exits.group[facets[~inside]], moved_i[i, ~inside], len(exits.names))
    return rho, evacuated
