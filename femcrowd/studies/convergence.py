"""Convergence studies: error against mesh size and against run time.

A study runs one case on a refinement series (``mesh.refine`` = base + 0..N-1, or the mesh
files of ``[convergence] meshes``), possibly for several series (``--set-values`` options
such as ``scheme.transport=upwind,muscl`` and ``--cfl`` values), and measures the errors of
measures.py at the final time and chosen output times. The reference is the case's exact
solution (``[exact]``), otherwise the finest level of the same series (self-convergence).

Every run goes through the same loop as ``femcrowd run`` (the same steps, landing on the
frame times; a crowd that leaves early does not end it before time.end), without writing
files. Its run time is the set-up (mesh, desired velocity, assembly) plus the solver's own
stepping time, without output or measurement, with one BLAS thread whether the runs go
through dask or one after the other in this process (execute.py).
"""

import csv
import itertools
import json
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import skfem

from ..case import load_case
from ..driver import Simulation
from ..driver.output import prepare_output_dir
from ..driver.scene import check_building, check_transport_cfl
from ..errors import InputError, Interrupted, StudyFailed
from ..files import replaced, write_text
from ..macro.transport import TRANSPORTS
from ..mesh import Domain, load_domain
from ..plot.convergence import error_plot
from ..timer import Stopwatch
from .execute import StudyInterrupted, describe, execute
from .measures import METRICS, ExactReference, LevelReference, exact_solution, measure

#: the run-time columns of convergence.csv
TIMING = ("setup_seconds", "solve_seconds", "wall_seconds")
#: the pictures of a study's report
PLOTS = ("error_vs_h.png", "error_vs_time.png", "frontier.png")


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


def parse_set_values(items, file="--set-values") -> list:
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


def plan_study(case_dir, levels: int, overrides=(), cfls=(), set_values=(), times=()) -> tuple:
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
    first = base.path(meshes[0] if meshes else base["mesh"]["file"])
    building = load_domain(first, base["boundary"]["exits"], 0, base.file).z is not None
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
            if building:   # what a building cannot run yet (driver/scene.py), refused before any run as by femcrowd run
                check_building(case)
            tasks.append(Task(label, level, str(case_dir), tuple(overrides) + tuple(extra), measured,
                              exact is not None, case["time"]["cfl"], mesh, values=dict(combo)))
    return base, exact, tasks


def run_task(task: Task) -> dict:
    """Run one level to its measurement times; measure against the exact solution when there is one.

    Without one, return the states (rho, p per time) so that the client compares with the finest level.
    """
    case = load_case(task.case_dir, task.overrides)
    clock = Stopwatch()
    simulation = Simulation(case)
    setup = clock.seconds
    model, domain, rho_max = simulation.model, simulation.scene.domain, case["model"]["rho_max"]
    states = []

    def keep_state(recorder):
        h = recorder.history()
        states.append({"time": model.t, "steps": model.state.steps, "solve_seconds": float(h["step_seconds"].sum()),
                       "rho": model.state.density.copy(), "p": model.state.p.copy(),
                       "mass_error": float(h["mass_error"].max()), "rho_min": float(h["min_density"].min()) / rho_max,
                       "rho_max": float(h["max_density"].max()) / rho_max, "p_min": float(h["min_pressure"].min())})

    history = simulation.run(stops=task.times, on_stop=keep_state, stop_when_empty=False).history
    curve = np.column_stack([history["time"], history["evacuated"] / rho_max])
    result = {"setup_seconds": setup, "cells": domain.ncells, "h": domain.h, "curve": curve,
              "wall_seconds": setup + states[-1]["solve_seconds"], "has_exits": bool(domain.exit_group)}
    if task.exact:
        reference = ExactReference(exact_solution(case))
        result["rows"] = [_row(state, measure(domain, state, reference, curve)) for state in states]
    else:
        result["states"] = states
        result["mesh"] = (domain.points, domain.triangles)
    return result


def _row(state, metrics):
    return {k: v for k, v in state.items() if k not in ("rho", "p")} | metrics


def study(case_dir, levels: int, out=None, overrides=(), cfls=(), set_values=(), times=(), serial: bool = False,
          scheduler: str | None = None, force: bool = False, echo=None, quiet: bool = True) -> tuple[list, str, Path]:
    """Run a convergence study and write its report; returns (rows, report text, output dir).

    Ctrl-C, or runs that fail (the others go on): the report of the levels that finished is written (their errors
    where their reference is known: the exact solution, or a finished finest level), then Interrupted says which
    levels are kept, and where; StudyFailed also which runs failed, and why.
    """
    base, exact, tasks = plan_study(case_dir, levels, overrides, cfls, set_values, times)
    out_dir = prepare_output_dir(base.output_dir(out, "convergence"), base.file, force)
    reference = reference_curves(base)
    try:
        results = execute(run_task, tasks, serial, scheduler, echo=echo, keep_going=True, quiet=quiet)
    except StudyInterrupted as stop:
        finished = [None if r is None or "failed" in r else r for r in stop.results]
        raise Interrupted(_keep_finished(out_dir, base, exact, tasks, finished, reference)[0]) from None
    failed = [(describe(t), r["failed"]) for t, r in zip(tasks, results) if "failed" in r]
    if failed:
        finished = [None if "failed" in r else r for r in results]
        kept, text = _keep_finished(out_dir, base, exact, tasks, finished, reference, failed)
        raise StudyFailed(f"{len(failed)} of {len(tasks)} runs failed ({failed[0][0]}: {failed[0][1]}); {kept}", text)
    rows = collect_rows(tasks, results)
    text = write_report(out_dir, base, exact, tasks, rows, reference)
    return rows, text, out_dir


def _keep_finished(out_dir, case, exact, tasks, results, reference, failed=()) -> tuple[str, str]:
    """Write the report of the finished runs of an interrupted study, or of one with failed runs (their
    reasons listed); (the line that says what is kept, the report)."""
    finished = {}
    for task, result in zip(tasks, results):
        if result is not None:
            finished.setdefault(task.series, []).append(str(task.level))
    if not finished:
        return f"no level of the study had finished: nothing written in {out_dir}", ""
    levels = "; ".join(", ".join(v) if s == "default" else f"{s}: {', '.join(v)}" for s, v in finished.items())
    count = sum(map(len, finished.values()))
    what = f"{len(failed)} failed" if failed else "interrupted"
    text = write_report(out_dir, case, exact, tasks, collect_rows(tasks, results), reference,
                        incomplete=f"{what}: {count} of {len(tasks)} runs finished (levels {levels})",
                        failures=[f"failed: {name}: {reason}" for name, reason in failed])
    plural = "s" if count > 1 else ""
    return (f"finished level{plural} {levels} (of 0-{max(t.level for t in tasks)}) kept in "
            f"{out_dir}/convergence.csv and convergence.md"), text


def collect_rows(tasks: list, results: list) -> list:
    """One row per run and measurement time; self-convergence rows are measured here against the
    finest level of their series (which itself gets no error). An interrupted study's results are None
    for the runs that did not finish: they have no rows, nor have the errors of a series whose finest
    level did not finish."""
    rows = []
    by_series = {}
    for task, result in zip(tasks, results):
        by_series.setdefault(task.series, []).append((task, result))
    for series, runs in by_series.items():
        finest = runs[-1][1]
        if finest is not None and "rows" not in finest:
            ref = LevelReference(*finest["mesh"], finest["states"], finest["curve"], finest["has_exits"])
        for task, result in runs:
            if result is None:
                continue
            if "rows" in result:
                measured = result["rows"]
            elif finest is None or result is finest:
                measured = [_row(s, dict.fromkeys(METRICS, math.nan)) for s in result["states"]]
            else:
                domain = Domain(skfem.MeshTri(np.ascontiguousarray(result["mesh"][0].T),
                                              np.ascontiguousarray(result["mesh"][1].T)))
                measured = [_row(s, measure(domain, s, ref, result["curve"])) for s in result["states"]]
            for m in measured:
                rows.append({"series": series, "level": task.level, "mesh": task.mesh, "cfl": task.cfl,
                             "cells": result["cells"], "h": result["h"], **task.values,
                             "setup_seconds": result["setup_seconds"],
                             "wall_seconds": result["setup_seconds"] + m["solve_seconds"],
                             **{k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in m.items()}})
    return rows


def observed_orders(rows: list, metric: str) -> dict:
    """log(e_{i-1} / e_i) / log(h_{i-1} / h_i) between consecutive levels of the same series and time."""
    orders = {}
    for _, group in itertools.groupby(sorted(rows, key=lambda r: (r["series"], r["time"], r["level"])),
                                        key=lambda r: (r["series"], r["time"])):
        group = list(group)
        for prev, row in zip(group, group[1:]):
            e0, e1 = abs(prev[metric]), abs(row[metric])
            ok = e0 > 0 and e1 > 0 and math.isfinite(e0) and math.isfinite(e1) and prev["h"] != row["h"]
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


def write_report(out_dir, case, exact, tasks, rows, reference, incomplete: str | None = None, failures=()):
    """convergence.csv, convergence.md (tables with observed orders) and the two log-log plots.

    incomplete: the note heading the report of an interrupted study or of one with failed runs (`failures`: a
    line each), which has no plots (quicker to stop; those of an earlier study in the directory are removed:
    they would not match the tables)."""
    columns = ["series", "level", "mesh", "cfl", "cells", "h", "steps", "time", *TIMING, *METRICS,
               "mass_error", "rho_min", "rho_max", "p_min"]
    with replaced(out_dir / "convergence.csv", sync=True) as tmp, open(tmp, "w", newline="") as f:
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
             *([f"**{incomplete}**", "", *(f"- {line}" for line in failures), *([""] if failures else [])]
               if incomplete else []),
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
              *(["Plots: `error_vs_h.png`, `error_vs_time.png`"
                 + (" and `frontier.png` (with the published reference figures)." if reference else "."), ""]
                if not incomplete else [])]
    text = "\n".join(lines)
    write_text(out_dir / "convergence.md", text, sync=True)
    if incomplete:
        for name in PLOTS:
            (out_dir / name).unlink(missing_ok=True)
        return text
    write_plots(out_dir, case, rows, reference)
    return text


def write_plots(out_dir, case, rows, reference) -> None:
    """error_vs_h.png, error_vs_time.png and, with a published reference, frontier.png of the rows' last time."""
    metrics = _metrics_present(rows)
    final = [r for r in rows if r["time"] == max(x["time"] for x in rows)]
    title = case["title"] or case.directory.name
    labels = {m: METRICS[m] for m in metrics}
    error_plot(out_dir / PLOTS[0], final, labels, "h", "h: largest edge length (m)",
               f"{title}\nerror vs mesh size at t = {final[0]['time']:g}", slopes=True)
    error_plot(out_dir / PLOTS[1], final, labels, "wall_seconds",
               "run time (s): setup + time stepping, no output", f"{title}\nerror vs run time at t = "
               f"{final[0]['time']:g}", reference=reference)
    published = [m for m in metrics if any(metric == m for _, metric in reference)]
    if published:   # the frontier: the metrics of the published reference, larger
        error_plot(out_dir / PLOTS[2], final, {m: METRICS[m] for m in published}, "wall_seconds",
                   "run time (s): setup + time stepping, no output",
                   f"{title}\nerror vs run time at t = {final[0]['time']:g}, with the published reference",
                   reference=reference, size=(6.4, 4.8))


def replot(out_dir, case_dir) -> None:
    """Draw the plots of a finished study again from its convergence.csv (the case it ran: its title and
    reference), e.g. after a change of the pictures; the tables are left as they are."""
    out_dir = Path(out_dir)
    with open(out_dir / "convergence.csv", newline="") as f:
        rows = [{k: v if k in ("series", "mesh") else int(v) if k in ("level", "cells", "steps") else float(v)
                 for k, v in row.items()} for row in csv.DictReader(f)]
    case = load_case(case_dir)
    write_plots(out_dir, case, rows, reference_curves(case))
