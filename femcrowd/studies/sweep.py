"""Parameter sweeps (``femcrowd sweep``): a case run for every combination of parameter values, each run
in its own output directory, their summaries tabulated in sweep.csv, sweep.md and sweep.json. A run that
fails is a row too (status "failed", its reason); the others are tabulated, then StudyFailed says so."""

import csv
import itertools

from ..case import load_case
from ..driver import run
from ..driver.output import prepare_output_dir, write_json
from ..errors import InputError, StudyFailed
from ..files import replaced, write_text
from .convergence import Task, parse_set_values
from .execute import describe, execute

SUMMARY_COLUMNS = ("status", "steps", "final_time", "wall", "mass_error", "max_mass_error", "evacuated",
                   "evacuation_time", "min_density_ever", "max_density_ever", "max_pressure_ever")


def plan_sweep(case_dir, set_values, out=None, overrides=()):
    """One task per combination of the --set-values; each writes its own output directory."""
    base = load_case(case_dir, overrides)
    options = [[(key, v) for v in values] for key, values in parse_set_values(set_values)]
    if not options:
        raise InputError(base.file, "--set-values", None, "a sweep needs at least one --set-values")
    root = base.output_dir(out, "sweep")
    tasks = []
    for combo in itertools.product(*options):
        name = ",".join(f"{k}={v}" for k, v in combo)
        safe = "".join(c if c.isalnum() or c in "._=,-" else "_" for c in name)
        load_case(case_dir, list(overrides) + [f"{k}={v}" for k, v in combo])   # checked before any run
        tasks.append(Task(name, 0, str(case_dir), tuple(overrides) + tuple(f"{k}={v}" for k, v in combo),
                          (), False, out=str(root / safe), mesh=safe, values=dict(combo)))
    return base, root, tasks


def sweep_task(task):
    """Run one sweep member (frames, history, summary in its own directory)."""
    summary = run(load_case(task.case_dir, task.overrides), task.out).summary
    return {**{k: summary.get(k) for k in SUMMARY_COLUMNS if k != "wall"},
            "wall": summary["timing"]["wall"], "output_dir": summary["output_dir"]}


def _row(task, result) -> dict:
    """The table's row of one member: its values, its summary or, failed, its reason."""
    if "failed" in result:
        return {**task.values, **dict.fromkeys(SUMMARY_COLUMNS), "status": "failed", "output_dir": task.out,
                "reason": result["failed"]}
    return {**task.values, **result, "reason": None}


def sweep(case_dir, set_values, out=None, overrides=(), serial: bool = False, scheduler: str | None = None,
          force: bool = False, echo=None, quiet: bool = True) -> tuple:
    """Run every combination; write sweep.csv and sweep.md in the sweep directory. Returns (rows, text, dir).

    Runs that fail do not stop the others: all are tabulated, then StudyFailed names the failed ones."""
    base, root, tasks = plan_sweep(case_dir, set_values, out, overrides)
    root = prepare_output_dir(root, base.file, force)
    results = execute(sweep_task, tasks, serial, scheduler, echo=echo, keep_going=True, quiet=quiet)
    keys = list(tasks[0].values)
    rows = [_row(t, r) for t, r in zip(tasks, results)]
    columns = keys + list(SUMMARY_COLUMNS) + ["output_dir", "reason"]
    with replaced(root / "sweep.csv", sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows(rows)
    fmt = lambda v: f"{v:.4g}" if isinstance(v, float) else "-" if v is None else str(v)  # noqa: E731
    shown = columns[:-2]
    lines = [f"# Sweep: {base['title'] or base.directory.name}", "",
             "| " + " | ".join(shown) + " |", "|" + "---|" * len(shown)]
    lines += ["| " + " | ".join(fmt(r[c]) for c in shown) + " |" for r in rows]
    failed = [(describe(t), r["failed"]) for t, r in zip(tasks, results) if "failed" in r]
    if failed:
        lines += ["", f"**{len(failed)} of {len(rows)} runs failed:**", ""]
        lines += [f"- {name}: {reason}" for name, reason in failed]
    text = "\n".join(lines) + "\n"
    write_text(root / "sweep.md", text, sync=True)
    write_json(root / "sweep.json", rows)
    if failed:
        raise StudyFailed(f"{len(failed)} of {len(rows)} sweep runs failed ({failed[0][0]}: {failed[0][1]}); "
                          f"the table of all of them: {root}/sweep.csv and sweep.md", text)
    return rows, text, root
