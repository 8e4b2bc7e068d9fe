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
    mass, p_max, p_min = dot(area, rho), float(p.max()), float(p.min())
    return {
        "mass": mass, "evacuated": float(state.evacuated.sum()),
        "max_density": float(rho.max()), "min_density": float(rho.min()),
        "saturated_area": float(area[saturated].sum()),
        "max_pressure": p_max, "min_pressure": p_min,
        "pressure_unsaturated": float(np.abs(unsaturated_p).max()) if unsaturated_p.size else 0.0,
        "complementarity": float(np.max(np.abs(p * (1.0 - rho)))),
        "non_finite": non_finite(state, mass, p_max, p_min),
    }


def non_finite(state, mass: float, p_max: float, p_min: float) -> int:
    """The NaN and inf entries of the densities and of p (invisible in comparisons: NaN > 1 is False). Counted
    only when the mass (a sum of every population's density, times areas > 0) or the extremes of p are not
    finite: a NaN or inf anywhere makes them so."""
    if np.isfinite(mass) and np.isfinite(p_max) and np.isfinite(p_min):
        return 0
    return int(np.count_nonzero(~np.isfinite(state.rho)) + np.count_nonzero(~np.isfinite(state.p)))


def population_invariants(domain, state) -> dict:
    """Per population: its mass, its evacuated mass and its smallest density (several populations)."""
    mass = state.rho @ domain.area
    return {name: {"mass": float(mass[i]), "evacuated": float(state.evacuated[i].sum()),
                   "min_density": float(state.rho[i].min())} for i, name in enumerate(state.populations)}
