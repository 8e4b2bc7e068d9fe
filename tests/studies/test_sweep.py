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


def test_an_interrupted_sweep_keeps_its_finished_runs_and_says_so(tmp_path, monkeypatch):
    """Ctrl-C during the second run: one line saying how many runs finished (their directories kept), exit 130,
    no traceback."""
    from click.testing import CliRunner

    import femcrowd.studies.sweep as module
    from femcrowd.cli import main

    finished, run_one = [], module.sweep_task

    def second_interrupted(task):
        if finished:
            raise KeyboardInterrupt
        finished.append(run_one(task))
        return finished[-1]

    monkeypatch.setattr(module, "sweep_task", second_interrupted)
    result = CliRunner().invoke(main, ["sweep", str(CASES / "corridor-wall"), "--set-values",
                                       "scheme.transport=upwind,muscl", "--set", "time.end=0.2", "--serial",
                                       "--out", str(tmp_path / "sweep")])
    assert result.exit_code == 130, result.output
    assert result.stderr == ("femcrowd: interrupted; 1 of the study's 2 runs finished, their output directories are "
                             "kept (the study's table is not written: run it again)\n")
    summary = json.loads((Path(finished[0]["output_dir"]) / "summary.json").read_text())
    assert summary["status"] == "completed"
