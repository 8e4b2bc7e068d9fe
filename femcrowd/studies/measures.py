"""Errors of a computed state against a reference: the exact solution of the case, or the finest level
of a refinement series (docs/model.md, "Exact solutions"). The metrics, at a measurement time t:

    l1              sum_K |K| |rho_K - <rho>_K|           (<.>_K: cell average of the reference)
    l1_pixels       the same on a 50 x 50 pixel grid of the bounding box (both fields averaged on pixels;
                    rho_h exactly, through the cells' intersections with the pixels)
    symdiff         area of the symmetric difference of the saturated zones {rho >= 1 - 1e-9}
    front_error     front position read where the transverse (x) or angular (r) average of the
                    density crosses the mid-level of the jump at the front, minus the reference's
    evacuated_error max over the steps of |evacuated_h(t) - evacuated(t)|
    pressure_l2     (sum_K |K| (p_K - <p>_K)^2)^(1/2)
    w1, w2          Wasserstein distances of the normalised densities' marginals along the front
                    coordinate (POT); equal to the 2-D distances for these x- or r-symmetric solutions
"""

import functools
import inspect
import math

import numpy as np
import shapely
from scipy import sparse

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
FUNCTION_SAMPLES = 64  # samples per pixel side for the pixel averages of the reference (midpoint rule)
#: front geometry of the exact solutions: profile coordinate and the density level read at the front
#: (midway between 1 and the density just outside the saturated zone: (1 + a)/2, (1 + sqrt(a))/2, 1/2)
FRONTS = {WallAccumulation: ("x", lambda s: (1 + s.a) / 2),
          RadialConcentration: ("r", lambda s: (1 + math.sqrt(s.a)) / 2),
          SaturatedEvacuation: ("x", lambda s: 0.5)}


def exact_solution(case):
    """The case's [exact] solution object, or None (self-convergence)."""
    spec = case["exact"] or {"name": None}
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

    def pixel_averages(self, pixels, t):
        return pixels.of_function(self.density, t)


class LevelReference:
    """The finest level of a series as the reference (self-convergence)."""

    coordinate = None

    def __init__(self, points, triangles, states, curve, has_exits):
        self.points, self.triangles = points, triangles
        self.locator = PointLocator(points, triangles)
        self.pixels = None
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

    def pixel_averages(self, pixels, t):
        """Exact pixel averages of the finest level's cell-wise density, on the measured grid's pixels."""
        if self.pixels is None:
            self.pixels = Pixels(self.points, self.triangles, pixels.box)
        return self.pixels.of_cells(self.states[t]["rho"])


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
    """L1 distance of the pixel averages of rho_h and of the reference (PIXELS^2 pixels over the bounding box)."""
    pixels = _pixels_of(domain)
    diff = pixels.of_cells(rho) - reference.pixel_averages(pixels, t)
    return float(np.abs(diff).sum() * pixels.area)


@functools.lru_cache(maxsize=1)
def _pixels_of(domain):
    """The pixel grid of a domain, built once for the several states a study measures on it."""
    return Pixels(domain.points, domain.triangles)


class Pixels:
    """Averages on the PIXELS x PIXELS grid over a triangulation's bounding box, outside it counted as 0.

    A cell-wise constant field is averaged exactly, through the areas |K n P| of the cells' intersections
    with the pixels (shapely); a function by the midpoint rule on FUNCTION_SAMPLES^2 points a pixel, the
    points outside the triangulation left out. A midpoint rule would do for the cell-wise field only with
    many points in every cell: with a few per pixel it measures its own sampling (docs/convergence.md).
    """

    def __init__(self, points, triangles, box=None):
        self.points, self.triangles = points, triangles
        self.box = box if box is not None else (points.min(0), points.max(0))
        self.lo = self.box[0]
        self.size = (self.box[1] - self.lo) / PIXELS
        self.area = float(np.prod(self.size))
        self._locator = None
        corners = points[triangles]                                                   # (cells, 3, 2)
        first = np.clip(((corners.min(1) - self.lo) // self.size).astype(int), 0, PIXELS - 1)
        last = np.clip(((corners.max(1) - self.lo) // self.size).astype(int), 0, PIXELS - 1)
        one = np.all(first == last, axis=1)                                           # cells in one pixel
        e1, e2 = corners[one, 1] - corners[one, 0], corners[one, 2] - corners[one, 0]
        cells, pixels = [np.flatnonzero(one)], [first[one] @ [PIXELS, 1]]
        areas = [0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])]
        span = last - first
        for di in range(int(span[:, 0].max()) + 1):                                   # the others: clipped
            for dj in range(int(span[:, 1].max()) + 1):
                k = np.flatnonzero(~one & (di <= span[:, 0]) & (dj <= span[:, 1]))
                ij = first[k] + [di, dj]
                box = shapely.box(*(self.lo + ij * self.size).T, *(self.lo + (ij + 1) * self.size).T)
                cells.append(k)
                pixels.append(ij @ [PIXELS, 1])
                areas.append(shapely.area(shapely.intersection(shapely.polygons(corners[k]), box)))
        self.weights = sparse.csr_array((np.concatenate(areas) / self.area,
                                         (np.concatenate(pixels), np.concatenate(cells))),
                                        shape=(PIXELS * PIXELS, len(triangles)))
        self.covered = self.weights.sum(axis=1)                                      # area fraction in the mesh

    def of_cells(self, values):
        """Pixel averages of the field equal to values[K] on cell K (exact)."""
        return self.weights @ values

    def of_function(self, f, t):
        """Pixel averages of f(x, y, t) (midpoint rule), a row of pixels at a time."""
        n = FUNCTION_SAMPLES
        offsets = (np.arange(n) + 0.5) / n
        y = self.lo[1] + (np.arange(PIXELS * n) + 0.5) / n * self.size[1]
        out = np.empty((PIXELS, PIXELS))
        for i in range(PIXELS):
            X, Y = np.meshgrid(self.lo[0] + (i + offsets) * self.size[0], y, indexing="ij")
            values = f(X, Y, t)
            partial = np.broadcast_to(np.repeat(self.covered[i * PIXELS:(i + 1) * PIXELS] < 1 - 1e-9, n), X.shape)
            if partial.any():
                if self._locator is None:
                    self._locator = PointLocator(self.points, self.triangles)
                outside = self._locator(np.column_stack([X[partial], Y[partial]])) < 0
                values[partial] = np.where(outside, 0.0, values[partial])
            out[i] = values.reshape(n, PIXELS, n).mean(axis=(0, 2))
        return out.ravel()


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
