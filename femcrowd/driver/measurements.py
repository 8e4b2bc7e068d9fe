"""Measurement lines and areas (``[[measure.lines]]``, ``[[measure.areas]]``): measurements.csv.

Lines count what crosses them from the left of from -> to to its right, as PedPy's N-t curves do
(Juelich Supercomputing Centre, PedPy 2023; the flow through a door of the RiMEA guideline, 2022).

- Macro: the mass the scheme itself moves across facets in a step, the transport's facet fluxes
  plus the pressure's T_e (phi_K - phi_L). The facets of a line are those whose dual edge (the
  segment between the centroids of their two cells; across a boundary facet, between the centroid
  and its mirror image) crosses the line, with the facet's midpoint within the line's span. For a
  line along mesh edges these are exactly its edges and the count is exact (an exit's count is its
  evacuated mass); a line across cells is counted on the staircase of facets nearest to it, which
  lies within one cell of the line: a conservative count (mass moves from one side of the
  staircase to the other), shifted in time by at most the time the crowd takes to cross one cell.
- Micro: the signed crossings of the segments q^n -> q^{n+1} of the discs (those that leave
  through an exit included); and, as PedPy's N-t curve counts them, the discs that have crossed the line
  at least once in either direction (``<line>_passed``, each disc at its first crossing; a move that ends
  on the line crosses it at the next move).

Areas give the mean density (over the area's part inside the domain), the mean speed of the
people in it (density-weighted) and the maximum pressure of the cells or discs in it. Macro cells
are weighted by their exact overlap with the polygon (shapely); discs count by their centres and
a disc is rho_max x (pi r^2 / hexagonal packing) of density unit x m^2, the conversion of the
initial sampling.
"""

from dataclasses import dataclass

import numpy as np
import shapely

from ..case import Case
from ..errors import InputError
from ..macro.lines import LineFlux
from ..macro.reconstruction import CellMean
from ..mesh import Domain
from ..mesh.outline import walkable_area
from ..micro.crossings import segment_crossings
from ..micro.sampling import HEX_PACKING
from .recorder import Column, Recorder


@dataclass
class Line:
    """A counting line: its ends, its facets (macro) and the sign of each facet's flux f2t[0] -> f2t[1]."""

    name: str
    a: np.ndarray
    b: np.ndarray
    facets: np.ndarray
    sign: np.ndarray


@dataclass
class Area:
    """A measurement area: the polygon, and the cells it overlaps with the overlap areas."""

    name: str
    polygon: object
    cells: np.ndarray
    weights: np.ndarray


def read_measurements(case: Case, domain: Domain):
    """The [[measure.lines]] and [[measure.areas]] of a case, checked against the mesh: (lines, areas)."""
    spec = case["measure"]
    if not spec["lines"] and not spec["areas"]:
        return [], []
    walkable = walkable_area(domain)
    tol = 1e-9 * max(np.ptp(domain.points, axis=0))
    lines, areas, names = [], [], set()

    def unique(key, name):
        if name in names:
            raise InputError(case.file, f"{key}.name", name, "is the name of another line or area")
        names.add(name)

    for i, item in enumerate(spec["lines"]):
        key = f"measure.lines[{i}]"
        unique(key, item["name"])
        a, b = np.array(item["from"]), np.array(item["to"])
        if np.linalg.norm(b - a) <= tol:
            raise InputError(case.file, f"{key}.to", item["to"], "the line has zero length (from = to)")
        if not walkable.buffer(10 * tol).covers(shapely.LineString([a, b])):
            raise InputError(case.file, key, f"{item['from']} -> {item['to']}", "the line leaves the domain")
        lines.append(Line(item["name"], a, b, *line_facets(domain, a, b)))
    for i, item in enumerate(spec["areas"]):
        key = f"measure.areas[{i}]"
        unique(key, item["name"])
        polygon = shapely.Polygon(item["polygon"])
        if not polygon.is_valid:
            raise InputError(case.file, f"{key}.polygon", item["polygon"],
                             f"not a simple polygon ({shapely.is_valid_reason(polygon)})")
        cells, weights = overlap(domain, polygon)
        if weights.sum() <= tol:
            raise InputError(case.file, f"{key}.polygon", item["polygon"], "the area lies outside the domain")
        areas.append(Area(item["name"], polygon, cells, weights))
    return lines, areas


def line_facets(domain: Domain, a: np.ndarray, b: np.ndarray):
    """The facets whose dual edge crosses the line a -> b (midpoints within its span) and the sign of each:
    +1 where f2t[0] is on the left, so that sign x (flux f2t[0] -> f2t[1]) counts left to right."""
    d = b - a
    k0, k1 = domain.f2t
    c0 = domain.centroid[k0]
    mirror = c0 + 2 * np.einsum("ij,ij->i", domain.midpoint - c0, domain.normal)[:, None] * domain.normal
    c1 = np.where(domain.interior[:, None], domain.centroid[np.maximum(k1, 0)], mirror)
    side = lambda p: d[0] * (p[:, 1] - a[1]) - d[1] * (p[:, 0] - a[0])  # noqa: E731  (> 0: left)
    s0, s1 = side(c0), side(c1)
    t = (domain.midpoint - a) @ d / (d @ d)
    facets = np.flatnonzero((s0 * s1 < 0) & (t >= -1e-9) & (t <= 1 + 1e-9))
    return facets, np.sign(s0[facets])


def overlap(domain: Domain, polygon):
    """The cells that overlap the polygon and the areas of the overlaps (shapely, vectorised)."""
    lo, hi = np.array(polygon.bounds[:2]), np.array(polygon.bounds[2:])
    corners = domain.points[domain.triangles]
    near = np.flatnonzero(np.all(corners.max(1) >= lo, axis=1) & np.all(corners.min(1) <= hi, axis=1))
    weights = shapely.area(shapely.intersection(shapely.polygons(corners[near]), polygon))
    keep = weights > 0
    return near[keep], weights[keep]


def measurement_columns(lines, areas, line_columns=("flow", "count")) -> list:
    """The columns of measurements.csv: time, per line flow and count (and passed, discs), per area density,
    speed, pressure."""
    names = ["time"] + [f"{line.name}_{q}" for line in lines for q in line_columns]
    names += [f"{area.name}_{q}" for area in areas for q in ("density", "speed", "pressure")]
    return [Column(name) for name in names]


class MacroMeasurements:
    """The hooks of a macro run's measurements: what crossed the lines in the step (macro/lines.py), the areas'
    means.

    Also keeps the maximum density of each cell over the run (the ``max_density`` cell field of the
    frames, for the level-of-service map of ``femcrowd plot``).
    """

    def __init__(self, lines, areas, domain: Domain, rho_max: float):
        self.lines, self.areas, self.domain, self.rho_max = lines, areas, domain, rho_max
        self.recorder = Recorder(measurement_columns(lines, areas))
        self.flux = LineFlux(domain, np.concatenate([line.facets for line in lines]),
                             np.concatenate([line.sign for line in lines]),
                             np.concatenate([np.full(len(line.facets), k) for k, line in enumerate(lines)]),
                             len(lines)) if lines else None
        self.count = np.zeros(len(lines))
        self.max_density = None
        # the velocity of the areas' cells (from their facets alone), and where each area's cells are among them
        cells = np.unique(np.concatenate([area.cells for area in areas])) if areas else np.zeros(0, np.intp)
        self.area_velocity = CellMean(domain, cells)
        self.area_rows = [np.searchsorted(cells, area.cells) for area in areas]

    def attach(self, solver, state) -> None:
        """Register the hooks and record the initial row."""
        if self.flux is not None:
            solver.before_step.append(self.before_step)
        solver.after_step.append(self.after_step)
        self.max_density = state.density * self.rho_max
        self.recorder.add(self._row(solver, state, np.zeros(len(self.lines)), 0.0))

    def before_step(self, solver, state, dt) -> None:
        with solver.timers("measurements"):
            self.flux.before_step(solver, state, dt)

    def after_step(self, solver, state, result) -> None:
        with solver.timers("measurements"):
            through = self.flux.after_step(result) * self.rho_max if self.flux is not None else np.zeros(0)
            self.count += through
            np.maximum(self.max_density, state.density * self.rho_max, out=self.max_density)
            self.recorder.add(self._row(solver, state, through, result.dt))

    def snapshot(self) -> dict:
        return {"count": self.count.copy(), "max_density": self.max_density.copy(),
                **{f"row.{k}": np.asarray(v) for k, v in self.recorder.rows.items()}}

    def restore(self, data: dict) -> None:
        self.count, self.max_density = data["count"].copy(), data["max_density"].copy()
        self.recorder.restore({k[4:]: v for k, v in data.items() if k.startswith("row.")})

    def _row(self, solver, state, through, dt) -> dict:
        row = {"time": state.t}
        for k, line in enumerate(self.lines):
            row[f"{line.name}_flow"] = through[k] / dt if dt > 0 else 0.0
            row[f"{line.name}_count"] = self.count[k]
        if self.areas:
            density = state.density * self.rho_max
            speed = np.hypot(*solver.velocity_field(state, self.area_velocity).T)
            for area, rows in zip(self.areas, self.area_rows):
                rho, w = density[area.cells], area.weights
                mass = w @ rho
                row[f"{area.name}_density"] = mass / w.sum()
                row[f"{area.name}_speed"] = (w * rho) @ speed[rows] / mass if mass > 0 else 0.0
                row[f"{area.name}_pressure"] = float(state.p[area.cells].max())
        return row


class MicroMeasurements:
    """The measurements of a disc run: signed crossings of the lines, discs in the areas."""

    def __init__(self, lines, areas, rho_max: float):
        self.lines, self.areas, self.rho_max = lines, areas, rho_max
        self.recorder = Recorder(measurement_columns(lines, areas, ("flow", "count", "passed")))
        self.count = np.zeros(len(lines))
        self.crossed = np.zeros((0, len(lines)), bool)   # per disc id and line: has it crossed the line yet
        self.segments = np.array([[line.a, line.b] for line in lines]).reshape(-1, 2, 2)

    def start(self, sim) -> None:
        """The initial row."""
        self.recorder.add(self._row(sim.t, np.zeros(len(self.lines)), 0.0, sim.q, sim.r, np.zeros_like(sim.q),
                                    np.zeros(len(sim.q))))

    def snapshot(self) -> dict:
        return {"count": self.count.copy(), "crossed": self.crossed.copy(),
                **{f"row.{k}": np.asarray(v) for k, v in self.recorder.rows.items()}}

    def restore(self, data: dict) -> None:
        self.count, self.crossed = data["count"].copy(), data["crossed"].copy()
        self.recorder.restore({k[4:]: v for k, v in data.items() if k.startswith("row.")})

    def record(self, before: np.ndarray, ids: np.ndarray, sim, info) -> None:
        """A step's row from the centres and ids of the discs before it and their centres after the move
        (sim.moved_to, before removals)."""
        crossings = segment_crossings(before, sim.moved_to, self.segments)
        through = crossings.sum(axis=0, dtype=int)
        self.count += through
        if len(ids) and ids.max() >= len(self.crossed):
            self.crossed = np.pad(self.crossed, ((0, 2 * ids.max() + 1 - len(self.crossed)), (0, 0)))
        self.crossed[ids] |= crossings != 0
        self.recorder.add(self._row(sim.t, through, info.dt, info.q, info.r, info.u, info.pressure))

    def _row(self, t, through, dt, q, r, u, pressure) -> dict:
        row = {"time": t}
        passed = self.crossed.sum(axis=0)
        for k, line in enumerate(self.lines):
            row[f"{line.name}_flow"] = through[k] / dt if dt > 0 else 0.0
            row[f"{line.name}_count"] = self.count[k]
            row[f"{line.name}_passed"] = passed[k]
        for area in self.areas:
            inside = shapely.contains_xy(area.polygon, q[:, 0], q[:, 1]) if len(q) else np.zeros(0, bool)
            size = area.weights.sum()
            row[f"{area.name}_density"] = self.rho_max * np.pi * (r[inside] ** 2).sum() / HEX_PACKING / size
            row[f"{area.name}_speed"] = float(np.hypot(*u[inside].T).mean()) if inside.any() else 0.0
            row[f"{area.name}_pressure"] = float(pressure[inside].max()) if inside.any() else 0.0
        return row
