"""The actual velocity u = U - grad p per cell, for output: the lowest-order Raviart-Thomas cell mean
of the scheme's own facet fluxes (Raviart, Thomas 1977)."""

import numpy as np


def cell_mean(domain, G: np.ndarray, G1: np.ndarray | None = None) -> np.ndarray:
    """Cell means (1/|K|) sum_e G_e (m_e - g_K) of the RT0 field with facet fluxes G (oriented k0 -> k1);
    G1, if given, is the flux seen from the cells f2t[1] (for a field that is discontinuous across facets)."""
    k0, k1 = domain.f2t
    inner = domain.interior
    G1 = G if G1 is None else G1
    out = np.zeros((domain.ncells, 2))
    for c in range(2):
        out[:, c] = np.bincount(k0, G * (domain.midpoint[:, c] - domain.centroid[k0, c]), domain.ncells)
        out[:, c] -= np.bincount(k1[inner], G1[inner] * (domain.midpoint[inner, c]
                                                        - domain.centroid[k1[inner], c]), domain.ncells)
    return out / domain.area[:, None]


def pressure_velocity(domain, exits, p: np.ndarray, jump: np.ndarray = None) -> np.ndarray:
    """-grad p per cell, reconstructed from the two-point fluxes G_e = T_e (p_K - p_L - j_e) (p_L = 0 across an
    open exit, no flux through walls, j_e the pressure jump of a capped door facet)."""
    return cell_mean(domain, exits.pressure_flux(p, jump))


def actual_velocity(domain, exits, normal_velocity: np.ndarray, p: np.ndarray, jump: np.ndarray = None) -> np.ndarray:
    """u = U - grad p per cell from the facet fluxes |e| U.n (none through walls) plus the pressure
    fluxes. Hence u.n = 0 on walls and u = 0 where nothing moves (a closed saturated room);
    U(centroid) - grad p would be O(1) wrong there in the cells along the walls, whose U.n the
    scheme never transports."""
    flux = np.where(exits.wall, 0.0, normal_velocity) * domain.length
    return cell_mean(domain, *flux) + pressure_velocity(domain, exits, p, jump)
