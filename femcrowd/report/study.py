"""What the report of a study shows (``femcrowd report`` on the directory of ``femcrowd sweep``, ``convergence``,
``evacuation-times``, or any directory of run directories): the headline numbers of each run, their spread and
how they change from run to run (the convergence of a refinement series), the study's own tables and figures."""

import base64
import json
import warnings

import numpy as np

from ..driver.reading import read_history
from .numbers import share_times

#: a study's own files: its kind by the table it wrote
KINDS = {"sweep.md": "sweep", "evacuation.md": "evacuation times under refinement",
         "convergence.md": "convergence", "compare.md": "micro/macro comparison"}


def is_study(directory) -> bool:
    """A directory a study wrote (one of its tables), or one holding run directories and no frames of its own."""
    if any((directory / name).is_file() for name in KINDS):
        return True
    return not any(directory.glob("*.pvd")) and any(directory.glob("*/summary.json"))


def member(directory) -> dict:
    """The headline numbers of one run directory of the study."""
    summary = json.loads((directory / "summary.json").read_text())
    history = read_history(directory / "history.csv") if (directory / "history.csv").is_file() else {}
    shares = share_times(history) if history else {}
    return {"evacuation time": summary.get("evacuation_time"), **shares, "out": summary.get("evacuated"),
            "left": summary.get("remaining", {}).get("people")}


def spread(members: dict, columns) -> dict:
    """Mean, standard deviation (n - 1), min, max of each column over the runs, and the change between the last
    two runs (in the order of the study: the finest two levels of a refinement series)."""
    values = np.array([[np.nan if m[c] is None else m[c] for c in columns] for m in members.values()], float)
    if not len(values):
        return {}
    with warnings.catch_warnings():   # a column no run has (nan throughout) is nan, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        rows = {"mean": np.nanmean(values, axis=0), "std": np.nanstd(values, axis=0, ddof=1) if len(values) > 1
                else np.full(len(columns), np.nan), "min": np.nanmin(values, axis=0), "max": np.nanmax(values, axis=0)}
    if len(values) > 1:
        rows["last change"] = values[-1] - values[-2]
    return {name: dict(zip(columns, row)) for name, row in rows.items()}


def study_context(directory) -> dict:
    """The values of a study's page (report/page.py)."""
    kind = next((KINDS[name] for name in KINDS if (directory / name).is_file()), "runs")
    order = [json.loads((directory / "sweep.json").read_text())] if (directory / "sweep.json").is_file() else []
    runs = sorted(p.parent for p in directory.glob("*/summary.json"))
    if order:   # the sweep's order, the rows of sweep.json
        listed = [directory / p for p in (row.get("output_dir") for row in order[0]) if p]
        runs = [p for p in listed if (p / "summary.json").is_file()] or runs
    members = {p.name: member(p) for p in runs}
    columns = list(next(iter(members.values()))) if members else []
    return {"kind": kind, "members": members, "columns": columns, "spread": spread(members, columns),
            "note": "std: over the runs (n - 1); last change: the last run minus the one before it (for a "
                    "refinement series, the finest two levels).",
            "tables": {p.name: p.read_text() for p in sorted(directory.glob("*.md"))},
            "figures": {p.name: "data:image/png;base64," + base64.b64encode(p.read_bytes()).decode("ascii")
                        for p in sorted(directory.glob("*.png"))}}
