"""Errors of a computed state against a reference: the exact solution of the case, or the finest level
of a refinement series (docs/model.md, "Exact solutions"). The metrics, at a measurement time t:

    l1              sum_K |K| |rho_K - <rho>_K|           (<.>_K: cell average of the reference)
    l1_pixels       the same on a 50 x 50 pixel grid of the bounding box (both fields averaged on pixels)
    symdiff         area of the symmetric difference of the saturated zones {rho >= 1 - 1e-9}
    front_error     front position read where the transverse (x) or angular (r) average of the
                    density crosses the mid-level of the jump at the front, minus the reference's
    evacuated_error max over the steps of |evacuated_h(t) - evacuated(t)|
    pressure_l2     (sum_K |K| (p_K - <p>_K)^2)^(1/2)
    w1, w2          Wasserstein distances of the normalised densities' marginals along the front
                    coordinate (POT); equal to the 2-D distances for these x- or r-symmetric solutions
"""

import inspect
import math

import numpy as np

from ..errors import InputError
from ..macro.diagnostics import SATURATED
from ..macro.exact import SOLUTIONS, RadialConcentration, SaturatedEvacuation, WallAccumulation
from ..mesh import PointLocator

METRICS = {
    "l1": "L1 density error",
    "l1_pixels": "L1 density error, 50x50 pixels",
    "symdiff": "saturated zone: symmetric difference (m^2)",
    "front_error": "front position error (m)",
    "evacuated_error": "evacuated mass: max error over time",
    "pressure_l2": "pressure L2 error",
    "w1": "W1 distance (m)",
    "w2": "W2 distance (m)",
}
PIXELS = 50
PIXEL_SAMPLES = 8  # samples per pixel side (midpoint rule)
#: front geometry of the exact solutions: profile coordinate and the density level read at the front
#: (midway between 1 and the density just outside the saturated zone: (1 + a)/2, (1 + sqrt(a))/2, 1/2)
FRONTS = {WallAccumulation: ("x", lambda s: (1 + s.a) / 2),
          RadialConcentration: ("r", lambda s: (1 + math.sqrt(s.a)) / 2),
          SaturatedEvacuation: ("x", lambda s: 0.5)}


def exact_solution(case):
    """The case's [exact] solution object, or None (self-convergence)."""
    spec = case["exact"]
    given = {k: v for k, v in spec.items() if k != "name" and v is not None}
    if spec["name"] is None:
        if given:
            key = next(iter(given))
            raise InputError(case.file, f"exact.{key}", given[key], "exact.name is missing")
        return None
    cls = SOLUTIONS[spec["name"]]
    if cls not in FRONTS:
        raise InputError(case.file, "exact.name", spec["name"],
                         f"is a one-step solution, not a time-dependent one (use one of "
                         f"{', '.join(n for n, c in SOLUTIONS.items() if c in FRONTS)})")
    accepted = inspect.signature(cls).parameters
    for key, value in given.items():
        if key not in accepted:
            raise InputError(case.file, f"exact.{key}", value,
                             f"not a parameter of {spec['name']!r} (parameters: {', '.join(accepted)})")
    return cls(**given)


class ExactReference:
    """An exact solution (macro/exact.py) as the reference of a study."""

    def __init__(self, exact):
        self.exact = exact
        self.coordinate, level = FRONTS[type(exact)]
        self.level = level(exact)
        self.has_evacuated = hasattr(exact, "evacuated")

    def density(self, x, y, t):
        return self.exact.density(x, y, t)

    def pressure(self, x, y, t):
        return self.exact.pressure(x, y, t)

    def front(self, t):
        return self.exact.front(t)

    def evacuated(self, t):
        return np.array([self.exact.evacuated(s) for s in t])


class LevelReference:
    """The finest level of a series as the reference (self-convergence)."""

    coordinate = None

    def __init__(self, points, triangles, states, curve, has_exits):
        self.locator = PointLocator(points, triangles)
        self.states = {s["time"]: s for s in states}
        self.curve = curve
        self.has_evacuated = has_exits

    def _field(self, name, x, y, t):
        cell = self.locator(np.column_stack([x.ravel(), y.ravel()]))
        values = self.states[t][name]
        return np.where(cell >= 0, values[np.maximum(cell, 0)], 0.0).reshape(x.shape)

    def density(self, x, y, t):
        return self._field("rho", x, y, t)

    def pressure(self, x, y, t):
        return self._field("p", x, y, t)

    def evacuated(self, t):
        return np.interp(t, self.curve[:, 0], self.curve[:, 1])


def measure(domain, state: dict, reference, curve) -> dict:
    """All metrics of one state against a reference (see METRICS)."""
    t, rho, p = state["time"], state["rho"], state["p"]
    area = domain.area
    ref_rho = domain.cell_average(reference.density, t=t)
    ref_sat = domain.cell_average(lambda x, y, s: reference.density(x, y, s) >= SATURATED, t=t)
    ref_p = domain.cell_average(reference.pressure, t=t)
    out = {"l1": float(area @ np.abs(rho - ref_rho)),
           "symdiff": float(area @ np.where(rho >= SATURATED, 1.0 - ref_sat, ref_sat)),
           "pressure_l2": float(np.sqrt(area @ (p - ref_p) ** 2))}
    out["l1_pixels"] = _pixel_l1(domain, rho, reference, t)
    if reference.has_evacuated:
        steps = curve[curve[:, 0] <= t + 1e-12]
        out["evacuated_error"] = float(np.max(np.abs(steps[:, 1] - reference.evacuated(steps[:, 0]))))
    else:
        out["evacuated_error"] = math.nan
    if reference.coordinate is None:
        out.update(front_error=math.nan, w1=math.nan, w2=math.nan)
        return out
    reader = FrontReader(domain, reference.coordinate)
    out["front_error"] = reader(rho, reference.level) - reference.front(t)
    out.update(_wasserstein(domain, rho, ref_rho, reference.coordinate))
    return out


def _pixel_l1(domain, rho, reference, t):
    """L1 distance of the pixel averages (PIXELS^2 pixels over the bounding box, midpoint rule)."""
    lo, hi = domain.points.min(0), domain.points.max(0)
    n = PIXELS * PIXEL_SAMPLES
    xs = lo[0] + (np.arange(n) + 0.5) * (hi[0] - lo[0]) / n
    ys = lo[1] + (np.arange(n) + 0.5) * (hi[1] - lo[1]) / n
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    cell = domain.locate(np.column_stack([X.ravel(), Y.ravel()])).reshape(X.shape)
    inside = cell >= 0
    computed = np.where(inside, rho[np.maximum(cell, 0)], 0.0)
    exact = np.where(inside, reference.density(X, Y, t), 0.0)
    diff = (computed - exact).reshape(PIXELS, PIXEL_SAMPLES, PIXELS, PIXEL_SAMPLES).mean(axis=(1, 3))
    return float(np.abs(diff).sum() * np.prod(hi - lo) / PIXELS ** 2)


class FrontReader:
    """Front position: where the transverse (x) or angular (r) average of a density first drops
    below a level, going out from x = 0 or r = 0 (linear interpolation between samples)."""

    def __init__(self, domain, coordinate, transverse=256):
        lo, hi = domain.points.min(0), domain.points.max(0)
        step = domain.h / 4
        if coordinate == "r":
            self.positions = np.arange(step / 2, min(np.abs(lo).min(), hi.min()), step)
            angle = 2 * np.pi * (np.arange(transverse) + 0.5) / transverse
            x, y = np.multiply.outer(self.positions, np.cos(angle)), np.multiply.outer(self.positions, np.sin(angle))
        else:
            self.positions = np.arange(max(lo[0], 0.0) + step / 2, hi[0], step)
            ys = lo[1] + (np.arange(transverse) + 0.5) * (hi[1] - lo[1]) / transverse
            x, y = np.meshgrid(self.positions, ys, indexing="ij")
        self.cell = domain.locate(np.column_stack([np.ravel(x), np.ravel(y)])).reshape(x.shape)
        self.weight = (self.cell >= 0).sum(1)

    def profile(self, rho):
        values = np.where(self.cell >= 0, rho[np.maximum(self.cell, 0)], 0.0)
        return values.sum(1) / np.maximum(self.weight, 1)

    def __call__(self, rho, level):
        prof, x = self.profile(rho), self.positions
        below = np.flatnonzero(prof < level)
        if not below.size:
            return float(x[-1])
        j = below[0]
        if j == 0:
            return 0.0
        return float(x[j - 1] + (prof[j - 1] - level) / (prof[j - 1] - prof[j]) * (x[j] - x[j - 1]))


def _wasserstein(domain, rho, ref_rho, coordinate):
    """W1, W2 between the normalised densities' marginals along the front coordinate (POT), each
    cell's mass placed at the cell's mean coordinate (the same points for both densities)."""
    import ot

    where = domain.cell_average(lambda x, y, t: np.hypot(x, y) if coordinate == "r" else x)
    u, v = rho * domain.area, ref_rho * domain.area
    if u.sum() <= 0 or v.sum() <= 0:
        return {"w1": math.nan, "w2": math.nan}
    return {f"w{p}": float(ot.wasserstein_1d(where, where, u / u.sum(), v / v.sum(), p=p) ** (1 / p))
            for p in (1, 2)}
