"""Evacuation times under refinement: the headline answer of a scene, checked for mesh convergence.

A study runs one macro case on a refinement series (the levels and series of a convergence study,
convergence.plan_study: ``mesh.refine`` = base + 0..N-1, ``--set-values``, ``--cfl``) until the crowd has
left, and reads on each level the times at which 50 %, 90 %, 99 % and all but ``time.empty_fraction`` of the
crowd are out, and the last person's: when all but half a person (LAST) are out, the time an agent model
or a drill quotes. For each time it reports the difference d_k = t_k - t_{k-1} between consecutive levels and the
observed order

    p_k = log(|d_{k-1}| / |d_k|) / log(h_{k-1} / h_k),

and, where p_k > 0 and d_{k-1}, d_k have the same sign, Richardson's estimate of the converged time
t_k + d_k / ((h_{k-1} / h_k)^p_k - 1) (Richardson 1911; the generalised form of Roache 1998, ch. 5). Where the
sign changes the convergence is oscillatory and the estimate is not defined (Celik et al. 2008, J. Fluids Eng.
130, 078001): it would extrapolate along d_k, which the next level may reverse again. evacuation.csv also gives
each level's flow, persons per second while 20 to 80 % of the crowd are out (validation.flow).

A study may join the levels of an earlier one of the same case and settings (``--join``): a finer level run
alone is then tabulated with the coarser ones, its order read on all of them.
"""

import csv
import math
import os
from pathlib import Path

import numpy as np

from ..case import load_case
from ..driver import Simulation
from ..driver.output import prepare_output_dir
from ..errors import InputError, Interrupted, StudyFailed, not_a_file
from ..files import replaced, write_text
from ..timer import Stopwatch
from .convergence import plan_study
from .execute import StudyInterrupted, describe, execute
from .settings import with_settings
from .validation import flow

#: the shares of the crowd out whose times are measured; then all but time.empty_fraction, and all but LAST persons
SHARES = (0.5, 0.9, 0.99)
#: the last person is out when fewer than this many persons are inside (the crowd's mass in persons)
LAST = 0.5
#: the columns of evacuation.csv before the times; the text ones, the whole numbers
LEVEL_COLUMNS = ("series", "level", "mesh", "cfl", "cells", "h", "steps", "wall_seconds", "cpu_seconds", "flow")
TEXT, WHOLE = ("series", "mesh"), ("level", "cells", "steps")
#: the columns a run measures (0 or nan for a level that did not finish)
MEASURED = LEVEL_COLUMNS[4:]


def evacuation_times(time, evacuated, total, shares) -> list:
    """The first times at which ``evacuated`` reaches each share of ``total`` (linear between the steps;
    nan when it never does)."""
    time, evacuated = np.r_[0.0, time], np.r_[0.0, evacuated]
    times = []
    for share in shares:
        k = int(np.searchsorted(evacuated >= share * total, True))   # evacuated is non-decreasing
        if k == len(evacuated):
            times.append(math.nan)
        elif k == 0:
            times.append(0.0)
        else:
            e0, e1 = evacuated[k - 1], evacuated[k]
            times.append(float(time[k - 1] + (share * total - e0) / (e1 - e0) * (time[k] - time[k - 1])))
    return times


def share_names(case) -> list:
    return [f"{100 * s:g} %" for s in SHARES] + [f"all but {case['time']['empty_fraction']:g}", "last person"]


def shares(case, total) -> tuple:
    """The shares of ``total`` (persons) whose times are read: SHARES, all but time.empty_fraction, all but LAST
    persons (nan for a crowd of at most LAST persons)."""
    return (*SHARES, 1.0 - case["time"]["empty_fraction"], 1.0 - LAST / total if total > LAST else math.nan)


def run_level(task) -> dict:
    """One level: run until the crowd has left (or time.end); its evacuation times."""
    case = load_case(task.case_dir, task.overrides)
    clock = Stopwatch()
    simulation = Simulation(case)
    result = simulation.run()
    h = result.history
    total = h["mass"][0] + (h["inflow"][-1] if "inflow" in h else 0.0)   # everyone who was ever inside
    return {"cells": simulation.scene.domain.ncells, "h": simulation.scene.domain.h, "steps": len(h["time"]) - 1,
            "wall_seconds": clock.seconds, "cpu_seconds": clock.cpu,
            "times": evacuation_times(h["time"], h["evacuated"], total, shares(case, total)),
            "flow": flow(h["time"], h["evacuated"], total)}


def observed(values, h) -> tuple[list, list, list]:
    """Differences between consecutive levels, observed orders and Richardson estimates (nan where undefined)."""
    n = len(values)
    diffs = [math.nan] + [values[k] - values[k - 1] for k in range(1, n)]
    orders, limits = [math.nan] * n, [math.nan] * n
    for k in range(2, n):
        d0, d1, ratio = abs(diffs[k - 1]), abs(diffs[k]), h[k - 1] / h[k]
        if d0 > 0 and d1 > 0 and ratio > 1:
            orders[k] = math.log(d0 / d1) / math.log(ratio)
            if orders[k] > 0 and diffs[k - 1] * diffs[k] > 0:
                limits[k] = values[k] + diffs[k] / (ratio ** orders[k] - 1)
    return diffs, orders, limits


def study(case_dir, levels: int, out=None, overrides=(), cfls=(), set_values=(), serial: bool = False,
          scheduler: str | None = None, force: bool = False, echo=None, quiet: bool = True,
          settings: str = "case", join=None) -> tuple[list, str, object]:
    """Run the refinement series and write evacuation.csv and evacuation.md; (rows, report text, directory).
    settings: "case", "recommended" or "fast" (studies/settings.py: the recommended settings on the case, with the
    recommended or the fast step, before overrides). join: the directory of an earlier study whose levels are
    tabulated with these (read_levels, joined).

    A level that fails or is not reached (Ctrl-C) has no times (nan); the others are tabulated, and StudyFailed
    or Interrupted then says which did not finish, as in a convergence study."""
    overrides = with_settings(case_dir, settings, overrides)
    base, _, tasks = plan_study(case_dir, levels, overrides, cfls, set_values)
    if base["model"]["type"] != "macro":
        raise InputError(base.file, "model.type", base["model"]["type"],
                         "evacuation times under mesh refinement are a macro study (discs: femcrowd sweep over seeds)")
    if not base["boundary"]["exits"]:
        raise InputError(base.file, "boundary.exits", [], "a scene without exits has no evacuation time")
    names = share_names(base)
    out_dir = base.output_dir(out, "evacuation")
    earlier = [] if join is None else read_levels(join, {t.series for t in tasks}, names, out_dir)
    out_dir = prepare_output_dir(out_dir, base.file, force)
    try:
        results = execute(run_level, tasks, serial, scheduler, echo=echo, keep_going=True, quiet=quiet)
        stopped = None
    except StudyInterrupted as stop:
        results, stopped = stop.results, stop
    rows = [{"series": t.series, "level": t.level, "mesh": t.mesh, "cfl": t.cfl,
             **({k: r[k] for k in MEASURED} if _finished(r) else {k: 0 if k in WHOLE else math.nan for k in MEASURED}),
             **{f"t {name}": v for name, v in zip(names, r["times"] if _finished(r) else [math.nan] * len(names))}}
            for t, r in zip(tasks, results)]
    failed = [(describe(t), r["failed"]) for t, r in zip(tasks, results) if r is not None and "failed" in r]
    kept = f"the finished levels kept in {out_dir}/evacuation.md and evacuation.csv"
    mismatch = joined_from = None
    if earlier and stopped is None and not failed:
        try:
            rows, joined_from = joined(earlier, rows, Path(join) / "evacuation.csv"), join
        except InputError as err:   # this run's levels are written all the same
            mismatch = InputError(err.file, err.key, err.value, f"{err.message}; not joined, {kept}")
    with replaced(out_dir / "evacuation.csv", sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    text = report(base, rows, names, overrides, joined_from) + "".join(
        f"\nfailed: {name}: {reason}" for name, reason in failed)
    write_text(out_dir / "evacuation.md", text, sync=True)
    if mismatch is not None:
        raise mismatch
    if stopped is not None:
        raise Interrupted(kept) from None
    if failed:
        raise StudyFailed(f"{len(failed)} of {len(tasks)} runs failed ({failed[0][0]}: {failed[0][1]}); {kept}", text)
    return rows, text, out_dir


def _finished(result) -> bool:
    return result is not None and "failed" not in result


def read_levels(directory, series, names, out_dir) -> list:
    """The levels of an earlier evacuation-times study (its evacuation.csv) to join with this one's: the same
    columns (shares), series of this study, every level finished. Read before this study runs; not its own --out,
    which the run clears."""
    file = Path(directory) / "evacuation.csv"
    if Path(directory).resolve() == Path(out_dir).resolve():
        raise InputError(file, "--join", str(directory), "is this study's own --out, which the run clears: "
                         "write the new levels to another directory")
    if not file.is_file():
        raise InputError(file, None, None, not_a_file(file, "evacuation.csv of an evacuation-times study"))
    columns = [*LEVEL_COLUMNS, *(f"t {n}" for n in names)]
    with open(file, newline="") as f:
        reader = csv.DictReader(f)
        if reader.fieldnames != columns:
            raise InputError(file, "columns", reader.fieldnames, f"expected this study's, {columns} (the same "
                             "time.empty_fraction)")
        try:
            rows = [{k: v if k in TEXT else int(v) if k in WHOLE else float(v) for k, v in row.items()}
                    for row in reader]
        except (TypeError, ValueError) as err:
            raise InputError(file, f"line {reader.line_num}", None, f"not a number: {err}") from None
    for r in rows:
        if r["series"] not in series:
            raise InputError(file, "series", r["series"], f"not a series of this study ({', '.join(sorted(series))})")
        if not math.isfinite(r["h"]):
            raise InputError(file, f"level {r['level']}", r["mesh"], "has no times: run it again rather than join it")
    return rows


def joined(earlier, rows, file) -> list:
    """This study's levels and an earlier study's, per series from the coarsest mesh to the finest, numbered
    again. A mesh run in both must have the same steps and times to the bit (the same case and settings);
    this run's row is kept."""
    mine = {(r["series"], r["mesh"]): r for r in rows}
    measured = ["steps"] + [k for k in rows[0] if k.startswith("t ")]
    for r in earlier:
        again = mine.get((r["series"], r["mesh"]))
        if again is not None and not np.array_equal([again[k] for k in measured], [r[k] for k in measured],
                                                    equal_nan=True):
            raise InputError(file, f"level {r['level']}", r["mesh"], "has other steps or times than this run on "
                             "the same mesh: not the same case or settings")
    merged = [r for r in earlier if (r["series"], r["mesh"]) not in mine] + rows
    levels = []
    for series in dict.fromkeys(r["series"] for r in rows):
        mesh_order = sorted((r for r in merged if r["series"] == series), key=lambda r: -r["h"])
        levels += [{**r, "level": k} for k, r in enumerate(mesh_order)]
    return levels


def report(case, rows, names, overrides=(), join=None) -> str:
    """The markdown tables: per series, per level the times; then per share the differences and orders."""
    lines = [f"# Evacuation times under refinement: {case['title'] or case.directory.name}", "",
             f"Case `{os.path.relpath(case.file)}`. Times (s) at which each share of the crowd is out; "
             "d: the change from the previous level, p: the observed order, t*: Richardson's estimate "
             "of the converged time.", ""]
    if overrides:
        lines += ["Overrides of the case (--settings, then --set): " + ", ".join(f"`{o}`" for o in overrides), ""]
    if join is not None:
        lines += [f"With the levels of `{os.path.join(join, 'evacuation.csv')}` (--join).", ""]
    for series in dict.fromkeys(r["series"] for r in rows):
        mine = [r for r in rows if r["series"] == series]
        lines += [f"## {series}", ""]
        head = ["level", "cells", "h (m)", "steps", "run time (s)", "CPU (s)"] + [f"t {n}" for n in names]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in mine:
            entries = [str(r["level"]), str(r["cells"]), _number(r["h"]), str(r["steps"]), _number(r["wall_seconds"]),
                       _number(r["cpu_seconds"])] + [_time(r[f"t {n}"]) for n in names]
            lines.append("| " + " | ".join(entries) + " |")
        lines += ["", "| share out | " + " | ".join(f"level {r['level']}: d (p)" for r in mine[1:])
                  + " | t* |", "|" + "---|" * (len(mine) + 1)]
        for n in names:
            values = [r[f"t {n}"] for r in mine]
            diffs, orders, limits = observed(values, [r["h"] for r in mine])
            cells = [(f"{d:+.3g}" if math.isfinite(d) else "-") + (f" ({p:.2f})" if math.isfinite(p) else "")
                     for d, p in zip(diffs[1:], orders[1:])]
            lines.append(f"| {n} | " + " | ".join(cells) + f" | {_time(limits[-1])} |")
        lines.append("")
    return "\n".join(lines)


def _time(t) -> str:
    return f"{t:.2f}" if math.isfinite(t) else "-"


def _number(x) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "-"
