"""Parameter sweeps: one run per combination of values, each in its own directory, and a table."""

import csv
import json
from pathlib import Path

from femcrowd.studies.sweep import sweep

from ..support import CASES


def test_sweep_writes_one_run_per_value_and_a_table(tmp_path):
    rows, text, root = sweep(CASES / "corridor-wall", ["scheme.transport=upwind,muscl"], out=tmp_path / "sweep",
                             overrides=["time.end=0.2", "output.every=0.2"], serial=True)
    assert [r["scheme.transport"] for r in rows] == ["upwind", "muscl"]
    for r in rows:
        summary = json.loads((Path(r["output_dir"]) / "summary.json").read_text())
        assert summary["status"] == "completed" and summary["case"]["scheme"]["transport"] == r["scheme.transport"]
        assert r["mass_error"] < 1e-10
    with open(root / "sweep.csv") as f:
        assert len(list(csv.DictReader(f))) == 2
    assert "| scheme.transport |" in (root / "sweep.md").read_text()
