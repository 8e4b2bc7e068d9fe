"""The invariants of a macro state (docs/model.md, "What every run shows"), in units of rho_max."""

import numpy as np

from ..linalg.vectors import dot

#: rho above this counts as saturated (the solver tolerance)
SATURATED = 1.0 - 1e-9


def invariants(domain, state) -> dict:
    """Mass, evacuated mass, density bounds, saturated area, pressure bounds, p off the saturated zone,
    complementarity max |p (1 - rho)|, and non-finite values of the state."""
    rho, p, area = state.density, state.p, domain.area
    saturated = rho >= SATURATED
    unsaturated_p = p[~saturated]
    return {
        "mass": dot(area, rho), "evacuated": float(state.evacuated.sum()),
        "max_density": float(rho.max()), "min_density": float(rho.min()),
        "saturated_area": float(area[saturated].sum()),
        "max_pressure": float(p.max()), "min_pressure": float(p.min()),
        "pressure_unsaturated": float(np.abs(unsaturated_p).max()) if unsaturated_p.size else 0.0,
        "complementarity": float(np.max(np.abs(p * (1.0 - rho)))),
        # NaN/inf would be invisible in the min/max above (comparisons with NaN are False): count them
        "non_finite": int(np.count_nonzero(~np.isfinite(state.rho)) + np.count_nonzero(~np.isfinite(p))),
    }


def population_invariants(domain, state) -> dict:
    """Per population: its mass, its evacuated mass and its smallest density (several populations)."""
    mass = state.rho @ domain.area
    return {name: {"mass": float(mass[i]), "evacuated": float(state.evacuated[i].sum()),
                   "min_density": float(state.rho[i].min())} for i, name in enumerate(state.populations)}
