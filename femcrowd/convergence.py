"""Convergence studies and parameter sweeps: error against mesh size and against run time.

A study runs one case on a refinement series (``mesh.refine`` = base + 0..N-1,
or the mesh files of ``[convergence] meshes``), possibly for several series
(``--set-values`` options such as ``scheme.transport=upwind,muscl`` and ``--cfl`` values),
and measures at the final time and chosen output times (design note, sec. 5):

    l1              sum_K |K| |rho_K - <rho>_K|           (<.>_K: cell average of the reference)
    l1_pixels       the same on a 50 x 50 pixel grid of the bounding box (both fields averaged on pixels)
    symdiff         area of the symmetric difference of the saturated zones {rho >= 1 - 1e-9}
    front_error     front position read where the transverse (x) or angular (r) average of the
                    density crosses the mid-level of the jump at the front, minus the reference's
    evacuated_error max over the steps of |evacuated_h(t) - evacuated(t)|
    pressure_l2     (sum_K |K| (p_K - <p>_K)^2)^(1/2)
    w1, w2          Wasserstein distances of the normalised densities' marginals along the front
                    coordinate (POT); equal to the 2-D distances for these x- or r-symmetric solutions

The reference is the case's exact solution (``[exact]``), otherwise the finest
level of the same series (self-convergence). The run time of a run is the
setup (mesh, desired velocity, assembly) plus the solver's own stepping time,
without output or measurement. Runs are independent and go through dask
(a LocalCluster on this machine's cores, an existing scheduler, or serial);
every number but the timings is identical whichever way they ran.
"""

import csv
import inspect
import itertools
import json
import math
import os
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import skfem
from scipy.spatial import cKDTree

from .case import load_case
from .errors import InputError
from .exact import SOLUTIONS, RadialConcentration, SaturatedEvacuation, WallAccumulation
from .macro import SATURATED, TRANSPORTS
from .mesh import Domain
from .output import prepare_output_dir, write_json
from .run import check_transport_cfl, run_macro, setup_macro

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
TIMING = ("setup_seconds", "solve_seconds", "wall_seconds")
PIXELS = 50
PIXEL_SAMPLES = 8  # samples per pixel side (midpoint rule)
#: front geometry of the exact solutions: profile coordinate and the density level read at the front
#: (midway between 1 and the density just outside the saturated zone: (1 + a)/2, (1 + sqrt(a))/2, 1/2)
FRONTS = {WallAccumulation: ("x", lambda s: (1 + s.a) / 2),
          RadialConcentration: ("r", lambda s: (1 + math.sqrt(s.a)) / 2),
          SaturatedEvacuation: ("x", lambda s: 0.5)}


# ---------------------------------------------------------------------------------------------
# the study plan


@dataclass
class Task:
    """One run of a study: a case with overrides, measured at ``times``."""

    series: str
    level: int
    case_dir: str
    overrides: tuple
    times: tuple
    exact: bool
    cfl: float = None
    mesh: str = ""
    out: str = ""
    values: dict = field(default_factory=dict)


def parse_set_values(items, file="--set-values"):
    """['key=v1,v2', 'key=["a, b", "c"]'] -> [(key, [value texts])]: comma-separated values, or a
    TOML array for values that contain commas; each value text is then read as by --set."""
    parsed = []
    for item in items:
        key, sep, text = (part.strip() for part in item.partition("="))
        if not sep or not key or not text:
            raise InputError(file, None, None, f"expected section.key=v1,v2,... (got {item!r})")
        if text.startswith("["):
            try:
                values = [json.dumps(v) if isinstance(v, str) else json.dumps(v).lower() if isinstance(v, bool)
                          else repr(v) for v in tomllib.loads(f"v = {text}")["v"]]
            except tomllib.TOMLDecodeError as err:
                raise InputError(file, key, text, f"not a TOML array: {err}") from None
        else:
            values = [v.strip() for v in text.split(",")]
        if not values or any(v == "" for v in values):
            raise InputError(file, key, text, "expected one or more comma-separated values")
        parsed.append((key, values))
    return parsed


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


def plan_study(case_dir, levels, overrides=(), cfls=(), set_values=(), times=()):
    """The tasks of a convergence study (every case is loaded and checked here, before any run)."""
    base = load_case(case_dir, overrides)
    exact = exact_solution(base)
    meshes = base["convergence"]["meshes"]
    if meshes and levels > len(meshes):
        raise InputError(base.file, "convergence.meshes", meshes,
                         f"--levels {levels} needs {levels} mesh files, the case lists {len(meshes)}")
    if levels < 2:
        raise InputError(base.file, "--levels", levels, "a study needs at least 2 levels")
    if base["time"]["dt"] is not None:
        raise InputError(base.file, "time.dt", base["time"]["dt"],
                         "a refinement study takes dt from the CFL number: remove time.dt")
    end = base["time"]["end"]
    bad = [t for t in times if not 0 < t <= end]
    if bad:
        raise InputError(base.file, "--times", bad[0], f"must be in (0, time.end = {end:g}]")
    measured = tuple(sorted(set(times) | {end}))
    options = [[(key, v) for v in values] for key, values in parse_set_values(set_values)]
    tasks = []
    for combo in itertools.product(*options, [("time.cfl", c) for c in cfls] or [None]):
        combo = [c for c in combo if c is not None]
        label = ", ".join(f"{k}={v}" for k, v in combo) or "default"
        for level in range(levels):
            extra = [f"{k}={v}" for k, v in combo]
            if meshes:
                path = base.path(meshes[level])
                extra.append(f"mesh.file={json.dumps(str(path))}")
                mesh = path.name
            else:
                extra.append(f"mesh.refine={base['mesh']['refine'] + level}")
                mesh = f"{Path(base['mesh']['file']).name} refine {base['mesh']['refine'] + level}"
            case = load_case(case_dir, list(overrides) + extra)
            check_transport_cfl(case, TRANSPORTS[case["scheme"]["transport"]])
            tasks.append(Task(label, level, str(case_dir), tuple(overrides) + tuple(extra), measured,
                              exact is not None, case["time"]["cfl"], mesh, values=dict(combo)))
    return base, exact, tasks


# ---------------------------------------------------------------------------------------------
# running tasks: serial or through dask


def execute(function, tasks, serial=False, scheduler=None, echo=None):
    """function(task) for every task, results in task order; through dask unless serial.

    Bigger runs are submitted with higher priority so that the longest one starts first.
    An InputError raised in a worker comes back as the same one-line error.
    """
    if serial:
        results = []
        for task in tasks:
            results.append(_unwrap(function(task)))
            _echo(echo, task, results[-1])
        return results
    import logging

    from dask.distributed import Client, LocalCluster, as_completed

    if not logging.getLogger("femcrowd").isEnabledFor(logging.INFO):   # dask's INFO chatter unless -v
        for name in ("distributed", "bokeh", "tornado"):
            logging.getLogger(name).setLevel(logging.ERROR)
    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    try:
        futures = [client.submit(function, task, pure=False, priority=task.level) for task in tasks]
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * len(tasks)
        for future in as_completed(futures):
            i = index[future.key]
            results[i] = _unwrap(future.result())
            _echo(echo, tasks[i], results[i])
        return results
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _unwrap(result):
    if "input_error" in result:
        raise InputError(*result["input_error"])
    return result


def _echo(echo, task, result):
    if echo is not None:
        what = task.series if task.out else f"{task.series}, level {task.level} ({task.mesh})"
        echo(f"  done: {what}: {result.get('wall_seconds', result.get('wall', 0.0)):.2f} s")


def _catching(function):
    """Run function(task); an InputError becomes a picklable result (InputError does not unpickle)."""
    def wrapped(task):
        try:
            return function(task)
        except InputError as err:
            return {"input_error": (err.file, err.key, err.value, err.message)}
    return wrapped


# ---------------------------------------------------------------------------------------------
# one run of a study


def run_task(task):
    """Run one level to its measurement times; measure against the exact solution when there is one.

    Without one, return the states (rho, p per time) so that the client compares with the finest level.
    """
    return _catching(_run_task)(task)


def _run_task(task):
    case = load_case(task.case_dir, task.overrides)
    tic = time.perf_counter()
    scene = setup_macro(case)
    setup = time.perf_counter() - tic
    solver, domain = scene.solver, scene.domain
    curve = [(0.0, 0.0)]
    inv = {"mass_error": 0.0, "rho_min": float(solver.rho.min()), "rho_max": float(solver.rho.max()),
           "p_min": 0.0}
    states, solve = [], 0.0
    for target in task.times:
        while solver.t < target:
            solve += solver.step(until=target)["step_seconds"]
            curve.append((solver.t, solver.evacuated))
            mass = float(np.sum(domain.area * solver.rho))
            inv["mass_error"] = max(inv["mass_error"], abs(mass + solver.evacuated - solver.initial_mass)
                                    / solver.initial_mass)
            inv["rho_min"] = min(inv["rho_min"], float(solver.rho.min()))
            inv["rho_max"] = max(inv["rho_max"], float(solver.rho.max()))
            inv["p_min"] = min(inv["p_min"], float(solver.p.min()))
        states.append({"time": solver.t, "steps": solver.step_count, "solve_seconds": solve,
                       "rho": solver.rho.copy(), "p": solver.p.copy(), **inv})
    result = {"setup_seconds": setup, "cells": domain.ncells, "h": domain.h, "curve": np.array(curve),
              "wall_seconds": setup + solve, "has_exits": bool(domain.exit.any())}
    if task.exact:
        exact = exact_solution(case)
        result["rows"] = [_row(state, measure(domain, state, ExactReference(exact), result["curve"]))
                          for state in states]
    else:
        result["states"] = states
        result["mesh"] = (domain.points, domain.triangles)
    return result


def _row(state, metrics):
    return {k: v for k, v in state.items() if k not in ("rho", "p")} | metrics


# ---------------------------------------------------------------------------------------------
# references and measurements


class ExactReference:
    """An exact solution of the design note as the reference of a study."""

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
        self.locator = Locator(points, triangles)
        self.states = {s["time"]: s for s in states}
        self.curve = curve
        self.has_evacuated = has_exits

    def _field(self, name, x, y, t):
        cell = self.locator(x.ravel(), y.ravel())
        values = self.states[t][name]
        return np.where(cell >= 0, values[np.maximum(cell, 0)], 0.0).reshape(x.shape)

    def density(self, x, y, t):
        return self._field("rho", x, y, t)

    def pressure(self, x, y, t):
        return self._field("p", x, y, t)

    def evacuated(self, t):
        return np.interp(t, self.curve[:, 0], self.curve[:, 1])


class Locator:
    """The cell containing each point (-1 outside): k nearest centroids, then a barycentric test."""

    def __init__(self, points, triangles):
        a, b, c = (points[triangles[:, k]] for k in range(3))
        self.tree = cKDTree((a + b + c) / 3)
        e1, e2 = b - a, c - a
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        # barycentric coordinates lambda_i = c_i0 + c_i1 x + c_i2 y, rows of the inverse affine map
        inv = np.stack([e2[:, 1], -e2[:, 0], -e1[:, 1], e1[:, 0]], 1) / det[:, None]
        self.coef = np.column_stack([-(inv[:, 0] * a[:, 0] + inv[:, 1] * a[:, 1]), inv[:, :2],
                                     -(inv[:, 2] * a[:, 0] + inv[:, 3] * a[:, 1]), inv[:, 2:]])
        self.ncells = len(triangles)

    def __call__(self, x, y, chunk=200_000):
        q = np.column_stack([np.ravel(x), np.ravel(y)])
        cell = np.full(len(q), -1)
        for start in range(0, len(q), chunk):
            todo = np.arange(start, min(start + chunk, len(q)))
            for k in (6, 40):
                if not todo.size:
                    break
                cand = self.tree.query(q[todo], k=min(k, self.ncells))[1].reshape(len(todo), -1)
                c = self.coef[cand]
                x, y = q[todo, 0, None], q[todo, 1, None]
                l1 = c[..., 0] + c[..., 1] * x + c[..., 2] * y
                l2 = c[..., 3] + c[..., 4] * x + c[..., 5] * y
                inside = (l1 >= -1e-12) & (l2 >= -1e-12) & (l1 + l2 <= 1 + 1e-12)
                hit = inside.any(1)
                cell[todo[hit]] = cand[hit, inside[hit].argmax(1)]
                todo = todo[~hit]
        return cell


def measure(domain, state, reference, curve, locator=None):
    """All metrics of one state against a reference (see the module docstring)."""
    t, rho, p = state["time"], state["rho"], state["p"]
    area = domain.area
    locator = locator or Locator(domain.points, domain.triangles)
    ref_rho = domain.cell_average(reference.density, t=t)
    ref_sat = domain.cell_average(lambda x, y, s: reference.density(x, y, s) >= SATURATED, t=t)
    ref_p = domain.cell_average(reference.pressure, t=t)
    out = {"l1": float(area @ np.abs(rho - ref_rho)),
           "symdiff": float(area @ np.where(rho >= SATURATED, 1.0 - ref_sat, ref_sat)),
           "pressure_l2": float(np.sqrt(area @ (p - ref_p) ** 2))}
    out["l1_pixels"] = _pixel_l1(domain, locator, rho, reference, t)
    if reference.has_evacuated:
        steps = curve[curve[:, 0] <= t + 1e-12]
        out["evacuated_error"] = float(np.max(np.abs(steps[:, 1] - reference.evacuated(steps[:, 0]))))
    else:
        out["evacuated_error"] = math.nan
    if reference.coordinate is None:
        out.update(front_error=math.nan, w1=math.nan, w2=math.nan)
        return out
    reader = FrontReader(domain, locator, reference.coordinate)
    out["front_error"] = reader(rho, reference.level) - reference.front(t)
    out.update(_wasserstein(domain, rho, ref_rho, reference.coordinate))
    return out


def _pixel_l1(domain, locator, rho, reference, t):
    """L1 distance of the pixel averages (PIXELS^2 pixels over the bounding box, midpoint rule)."""
    lo, hi = domain.points.min(0), domain.points.max(0)
    n = PIXELS * PIXEL_SAMPLES
    xs = lo[0] + (np.arange(n) + 0.5) * (hi[0] - lo[0]) / n
    ys = lo[1] + (np.arange(n) + 0.5) * (hi[1] - lo[1]) / n
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    cell = locator(X, Y).reshape(X.shape)
    inside = cell >= 0
    computed = np.where(inside, rho[np.maximum(cell, 0)], 0.0)
    exact = np.where(inside, reference.density(X, Y, t), 0.0)
    diff = (computed - exact).reshape(PIXELS, PIXEL_SAMPLES, PIXELS, PIXEL_SAMPLES).mean(axis=(1, 3))
    return float(np.abs(diff).sum() * np.prod(hi - lo) / PIXELS ** 2)


class FrontReader:
    """Front position: where the transverse (x) or angular (r) average of a density first drops
    below a level, going out from x = 0 or r = 0 (linear interpolation between samples)."""

    def __init__(self, domain, locator, coordinate, transverse=256):
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
        self.cell = locator(x, y).reshape(x.shape)
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


# ---------------------------------------------------------------------------------------------
# the study: rows, observed orders, report files


def study(case_dir, levels, out=None, overrides=(), cfls=(), set_values=(), times=(), serial=False,
          scheduler=None, force=False, echo=None):
    """Run a convergence study and write its report; returns (rows, report text, output dir)."""
    base, exact, tasks = plan_study(case_dir, levels, overrides, cfls, set_values, times)
    default = base.path(base["output"]["dir"]) / "convergence"
    out_dir = prepare_output_dir(Path(out).resolve() if out is not None else default, base.file, force)
    results = execute(run_task, tasks, serial, scheduler, echo=echo)
    rows = collect_rows(tasks, results)
    reference = reference_curves(base)
    text = write_report(out_dir, base, exact, tasks, rows, reference)
    return rows, text, out_dir


def collect_rows(tasks, results):
    """One row per run and measurement time; self-convergence rows are measured here against the
    finest level of their series (which itself gets no error)."""
    rows = []
    by_series = {}
    for task, result in zip(tasks, results):
        by_series.setdefault(task.series, []).append((task, result))
    for series, runs in by_series.items():
        finest = runs[-1][1]
        if "rows" not in finest:
            ref = LevelReference(*finest["mesh"], finest["states"], finest["curve"], finest["has_exits"])
        for task, result in runs:
            if "rows" in result:
                measured = result["rows"]
            else:
                domain = Domain(skfem.MeshTri(np.ascontiguousarray(result["mesh"][0].T),
                                              np.ascontiguousarray(result["mesh"][1].T)))
                locator = Locator(domain.points, domain.triangles)
                measured = [_row(s, measure(domain, s, ref, result["curve"], locator)
                                 if result is not finest else dict.fromkeys(METRICS, math.nan))
                            for s in result["states"]]
            for m in measured:
                rows.append({"series": series, "level": task.level, "mesh": task.mesh, "cfl": task.cfl,
                             "cells": result["cells"], "h": result["h"], **task.values,
                             "setup_seconds": result["setup_seconds"],
                             "wall_seconds": result["setup_seconds"] + m["solve_seconds"],
                             **{k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in m.items()}})
    return rows


def observed_orders(rows, metric):
    """log(e_{i-1} / e_i) / log(h_{i-1} / h_i) between consecutive levels of the same series and time."""
    orders = {}
    for _, group in itertools.groupby(sorted(rows, key=lambda r: (r["series"], r["time"], r["level"])),
                                        key=lambda r: (r["series"], r["time"])):
        group = list(group)
        for prev, row in zip(group, group[1:]):
            e0, e1 = abs(prev[metric]), abs(row[metric])
            ok = e0 > 0 and e1 > 0 and math.isfinite(e0) and math.isfinite(e1)
            orders[(row["series"], row["time"], row["level"])] = \
                math.log(e0 / e1) / math.log(prev["h"] / row["h"]) if ok else math.nan
    return orders


def reference_curves(case):
    """Published (method, metric) -> [(seconds, error)] from [convergence].reference, or {}."""
    name = case["convergence"]["reference"]
    if name is None:
        return {}
    path = case.path(name)
    try:
        with open(path, newline="") as f:
            table = list(csv.DictReader(f))
        curves = {}
        for row in table:
            curves.setdefault((row["method"], row["metric"]), []).append(
                (float(row["seconds"]), float(row["error"])))
    except (OSError, KeyError, ValueError, TypeError) as err:
        raise InputError(case.file, "convergence.reference", name,
                         f"cannot read a method,metric,seconds,error table: {err}") from None
    return curves


def _metrics_present(rows):
    return [m for m in METRICS if any(math.isfinite(r[m]) for r in rows)]


def write_report(out_dir, case, exact, tasks, rows, reference):
    """convergence.csv, convergence.md (tables with observed orders) and the two log-log plots."""
    columns = ["series", "level", "mesh", "cfl", "cells", "h", "steps", "time", "setup_seconds",
               "solve_seconds", "wall_seconds", *METRICS, "mass_error", "rho_min", "rho_max", "p_min"]
    with open(out_dir / "convergence.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    if exact is not None:
        params = ", ".join(f"{k} = {v:g}" for k, v in vars(exact).items() if k in case["exact"])
        against = f"exact solution `{case['exact']['name']}` ({params})"
    else:
        against = ("**self-convergence**: errors against the finest level of each series "
                   "(which has no error of its own)")
    metrics = _metrics_present(rows)
    lines = [f"# Convergence study: {case['title'] or case.directory.name}", "",
             f"Case `{os.path.relpath(case.file)}`, reference: {against}.", "",
             "Each cell: error (observed order against the previous level). Run time = setup + "
             "time stepping, without output or measurement.", ""]
    for t in sorted({r["time"] for r in rows}):
        lines += [f"## t = {t:g}", ""]
        orders = {m: observed_orders(rows, m) for m in metrics}
        head = ["series", "level", "cells", "h", "steps", "run time (s)"] + [METRICS[m] for m in metrics]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in (r for r in rows if r["time"] == t):
            cells = [r["series"], str(r["level"]), str(r["cells"]), f"{r['h']:.4g}", str(r["steps"]),
                     f"{r['wall_seconds']:.3g}"]
            for m in metrics:
                p = orders[m].get((r["series"], t, r["level"]), math.nan)
                value = f"{abs(r[m]):.3e}" if math.isfinite(r[m]) else "-"
                cells.append(value + (f" ({p:.2f})" if math.isfinite(p) else ""))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    worst = max((r["mass_error"] for r in rows), default=0.0)
    lines += [f"Invariants over all runs: max relative mass error {worst:.1e}, "
              f"min density {min(r['rho_min'] for r in rows):.3g}, "
              f"max density {max(r['rho_max'] for r in rows):.12g}, "
              f"min pressure {min(r['p_min'] for r in rows):.3g}.", "",
              "Plots: `error_vs_h.png`, `error_vs_time.png`"
              + (" and `frontier.png` (with the published reference figures)." if reference else "."), ""]
    text = "\n".join(lines)
    (out_dir / "convergence.md").write_text(text)
    final = [r for r in rows if r["time"] == max(x["time"] for x in rows)]
    title = case["title"] or case.directory.name
    plot(out_dir / "error_vs_h.png", final, metrics, "h", "h: largest edge length (m)",
         f"{title}\nerror vs mesh size at t = {final[0]['time']:g}", slopes=True)
    plot(out_dir / "error_vs_time.png", final, metrics, "wall_seconds",
         "run time (s): setup + time stepping, no output", f"{title}\nerror vs run time at t = "
         f"{final[0]['time']:g}", reference=reference)
    published = [m for m in metrics if any(metric == m for _, metric in reference)]
    if published:   # the frontier: the metrics of the published reference, larger
        plot(out_dir / "frontier.png", final, published, "wall_seconds",
             "run time (s): setup + time stepping, no output",
             f"{title}\nerror vs run time at t = {final[0]['time']:g}, with the published reference",
             reference=reference, size=(6.4, 4.8))
    return text


def plot(path, rows, metrics, x, xlabel, title, slopes=False, reference=None, size=(4.2, 3.6)):
    """One log-log panel per metric, one line per series (plus published reference curves)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    ncol = min(len(metrics), 4)
    nrow = -(-len(metrics) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(size[0] * ncol, size[1] * nrow + 0.8), squeeze=False)
    series = list(dict.fromkeys(r["series"] for r in rows))
    for ax, metric in zip(axes.flat, metrics):
        for s in series:
            pts = [(r[x], abs(r[metric])) for r in sorted(rows, key=lambda r: r["level"])   # in level order
                   if r["series"] == s and math.isfinite(r[metric]) and r[metric] != 0]
            if pts:
                ax.loglog(*zip(*pts), "o-", label=s)
        if slopes:
            pts = sorted((r[x], abs(r[metric])) for r in rows if math.isfinite(r[metric]) and r[metric] != 0)
            if len(pts) >= 2:
                h = np.array([pts[0][0], pts[-1][0]])
                for order, style in ((0.5, ":"), (1.0, "--")):
                    ax.loglog(h, pts[-1][1] * (h / h[-1]) ** order, "k" + style, lw=0.8, label=f"h^{order:g}")
        for (method, m), pts in (reference or {}).items():
            if m == metric:
                ax.loglog(*zip(*sorted(pts)), "s--", color="0.35" if "DG0" in method else "k", lw=1,
                          ms=4, label=method)
        ax.set_title(METRICS[metric], fontsize=9)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("error", fontsize=8)
        ax.grid(True, which="both", lw=0.3)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(_minor_label))
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6 if size[0] < 5 else 7)
    for ax in list(axes.flat)[len(metrics):]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _minor_label(x, pos):
    """Label the minor log ticks 2 and 5 of each decade (the others stay unlabelled)."""
    mantissa = x / 10 ** math.floor(math.log10(x) + 1e-9)
    return f"{x:g}" if any(abs(mantissa - m) < 1e-6 for m in (2, 5)) else ""


# ---------------------------------------------------------------------------------------------
# parameter sweeps

SUMMARY_COLUMNS = ("status", "steps", "final_time", "wall", "mass_error", "max_mass_error", "evacuated",
                   "evacuation_time", "min_density_ever", "max_density_ever", "max_pressure_ever")


def plan_sweep(case_dir, set_values, out=None, overrides=()):
    """One task per combination of the --set-values; each writes its own output directory."""
    base = load_case(case_dir, overrides)
    options = [[(key, v) for v in values] for key, values in parse_set_values(set_values)]
    if not options:
        raise InputError(base.file, "--set-values", None, "a sweep needs at least one --set-values")
    root = Path(out).resolve() if out is not None else base.path(base["output"]["dir"]) / "sweep"
    tasks = []
    for combo in itertools.product(*options):
        name = ",".join(f"{k}={v}" for k, v in combo)
        safe = "".join(c if c.isalnum() or c in "._=,-" else "_" for c in name)
        load_case(case_dir, list(overrides) + [f"{k}={v}" for k, v in combo])   # checked before any run
        tasks.append(Task(name, 0, str(case_dir), tuple(overrides) + tuple(f"{k}={v}" for k, v in combo),
                          (), False, out=str(root / safe), mesh=safe, values=dict(combo)))
    return base, root, tasks


def sweep_task(task):
    """Run one sweep member with run_macro (frames, history, summary in its own directory)."""
    return _catching(_sweep_task)(task)


def _sweep_task(task):
    summary = run_macro(load_case(task.case_dir, task.overrides), task.out, force=False, quiet=True)
    return {**{k: summary.get(k) for k in SUMMARY_COLUMNS if k != "wall"},
            "wall": summary["timing"]["wall"], "output_dir": summary["output_dir"]}


def sweep(case_dir, set_values, out=None, overrides=(), serial=False, scheduler=None, force=False, echo=None):
    """Run every combination; write sweep.csv and sweep.md in the sweep directory. Returns (rows, text, dir)."""
    base, root, tasks = plan_sweep(case_dir, set_values, out, overrides)
    root = prepare_output_dir(root, base.file, force)
    results = execute(sweep_task, tasks, serial, scheduler, echo=echo)
    keys = list(tasks[0].values)
    rows = [{**t.values, **r} for t, r in zip(tasks, results)]
    columns = keys + list(SUMMARY_COLUMNS) + ["output_dir"]
    with open(root / "sweep.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows(rows)
    fmt = lambda v: f"{v:.4g}" if isinstance(v, float) else "-" if v is None else str(v)  # noqa: E731
    lines = [f"# Sweep: {base['title'] or base.directory.name}", "",
             "| " + " | ".join(columns[:-1]) + " |", "|" + "---|" * (len(columns) - 1)]
    lines += ["| " + " | ".join(fmt(r[c]) for c in columns[:-1]) + " |" for r in rows]
    text = "\n".join(lines) + "\n"
    (root / "sweep.md").write_text(text)
    write_json(root / "sweep.json", rows)
    return rows, text, root
