"""The record of a run: one table of diagnostics gives both history.csv and the summary.

A model declares its :class:`Column` s: the name of a per-step value (one row per step,
and one for the initial state at t = 0), whether history.csv shows it, and what the
summary keeps of it (its last value, its maximum over the run, ...). The recorder keeps
the rows in memory (for the Python API) and hands each to a sink (history.csv).
"""

from dataclasses import dataclass

import numpy as np

#: what the summary can keep of a column, over all rows (the initial one included) or over the steps
REDUCTIONS = {
    "first": lambda v: v[0],
    "last": lambda v: v[-1],
    "min": np.min,
    "max": np.max,
    "sum": np.sum,
    "mean_over_steps": lambda v: np.mean(v[1:]) if len(v) > 1 else 0.0,
    "mean_positive": lambda v: np.mean(v[v > 0]) if np.any(v > 0) else 0.0,
    "count_positive": lambda v: np.count_nonzero(v > 0),
    "mean_finite": lambda v: np.mean(v[np.isfinite(v)]) if np.any(np.isfinite(v)) else None,
    "count_finite": lambda v: np.count_nonzero(np.isfinite(v)),
}


@dataclass(frozen=True)
class Column:
    """A per-step diagnostic: its name, whether history.csv shows it, and the summary entries made of it,
    as (summary key, reduction) pairs; a dotted key nests ("active_set_iterations.mean")."""

    name: str
    summary: tuple = ()
    history: bool = True


class Recorder:
    """Rows of diagnostics, one per step: kept, handed to the sink, reduced into the summary."""

    def __init__(self, columns, sink=None):
        self.columns = list(columns)
        self.sink = sink
        self.rows = {c.name: [] for c in self.columns}

    @property
    def history_columns(self) -> list:
        return [c.name for c in self.columns if c.history]

    def add(self, row: dict) -> None:
        for name, values in self.rows.items():
            values.append(row[name])
        if self.sink is not None:
            self.sink.append(row)

    def restore(self, rows: dict) -> None:
        """Continue the record of a resumed run (rows: one array per column)."""
        self.rows = {c.name: list(rows[c.name]) for c in self.columns}

    def records(self):
        """The rows so far, each as a dict."""
        names = list(self.rows)
        return (dict(zip(names, values)) for values in zip(*self.rows.values()))

    def history(self) -> dict:
        """The rows so far as arrays, one per column."""
        return {name: np.asarray(values) for name, values in self.rows.items()}

    def summary(self) -> dict:
        """The summary entries of every column, over the rows so far."""
        out = {}
        for column in self.columns:
            values = np.asarray(self.rows[column.name])
            for key, reduction in column.summary:
                value = REDUCTIONS[reduction](values) if len(values) else None
                *parents, leaf = key.split(".")
                target = out
                for parent in parents:
                    target = target.setdefault(parent, {})
                target[leaf] = value.item() if isinstance(value, np.generic) else value
        return out
