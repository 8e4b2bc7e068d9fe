"""Ctrl-C during a convergence study, or a run of it that fails: the finished levels are kept (report written),
one line says which and where, no traceback from the dask workers, exit code 130 as for `femcrowd run` (a
failed run: 1)."""

import csv
import math
import os
import re
import signal
import subprocess
import time

import pytest

from femcrowd.errors import Interrupted
from femcrowd.studies import convergence
from femcrowd.studies.measures import METRICS

from ..support import CASES, FEMCROWD


def test_sigint_to_a_dask_study_keeps_its_finished_levels(tmp_path):
    """A terminal's Ctrl-C goes to the process group (the study and its dask workers); sent once the first
    level is done. Level 3 of the corridor takes 2-4 s (dask starts the finest level first): it is still
    running then."""
    out = tmp_path / "study"
    proc = subprocess.Popen([str(FEMCROWD), "convergence", str(CASES / "corridor-wall"), "--levels", "4",
                             "--out", str(out), "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: (os.setsid(), signal.signal(signal.SIGINT, signal.SIG_DFL)))
    first = proc.stdout.readline()   # "  done: default, level k (...)": that level's result is with the client
    assert "done:" in first, first
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stdout + stderr
    [line] = stderr.strip().splitlines()
    kept = re.fullmatch(rf"femcrowd: interrupted; finished levels? ([\d, ]+) \(of 0-3\) kept in "
                        rf"{re.escape(str(out))}/convergence.csv and convergence.md", line)
    assert kept, line
    levels = [int(k) for k in kept.group(1).split(", ")]
    assert int(re.search(r"level (\d)", first).group(1)) in levels and 3 not in levels
    with open(out / "convergence.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(int(r["level"]) for r in rows) == levels
    assert all(0 < float(r["l1"]) < 0.05 for r in rows)   # measured against the exact solution
    assert "interrupted" in (out / "convergence.md").read_text()
    assert sorted(f.name for f in out.iterdir()) == [".femcrowd-lock", ".femcrowd-run", "convergence.csv",
                                                     "convergence.md"]
    deadline = time.monotonic() + 120   # no worker left behind (they end in a second or two: a bound for a hang)
    while time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.2)
    else:
        pytest.fail("processes of the study's group still alive 120 s after it ended")


def test_interrupted_self_convergence_keeps_the_levels_without_errors(tmp_path, monkeypatch):
    """Serial, in this process: Ctrl-C in level 1 of 3; level 0 is kept, without errors (its reference,
    the finest level, never ran)."""
    run_task = convergence.run_task

    def interrupted_at_level_1(task):
        if task.level == 1:
            raise KeyboardInterrupt
        return run_task(task)
    monkeypatch.setattr(convergence, "run_task", interrupted_at_level_1)
    with pytest.raises(Interrupted, match=r"finished level 0 \(of 0-2\) kept in .*convergence.csv"):
        convergence.study(CASES / "room", 3, out=tmp_path, overrides=["time.end=0.5"], serial=True)
    with open(tmp_path / "convergence.csv", newline="") as f:
        [row] = csv.DictReader(f)
    assert row["level"] == "0" and float(row["time"]) == 0.5 and int(row["steps"]) > 0
    assert all(math.isnan(float(row[m])) for m in METRICS)
    assert float(row["mass_error"]) < 1e-12
    assert "interrupted: 1 of 3 runs finished" in (tmp_path / "convergence.md").read_text()


def test_a_failed_level_leaves_the_finished_ones_reported(tmp_path, monkeypatch):
    """Level 1 of 3 of the corridor raises (a projection that does not converge, its message on two lines):
    levels 0 and 2 are reported against the exact solution, the failure listed with its one-line reason; the
    report is printed, then one line on stderr; exit code 1, no traceback (the study used to write nothing)."""
    from click.testing import CliRunner

    from femcrowd.cli import main
    from femcrowd.macro.projection.lcp import ProjectionError

    run_task = convergence.run_task

    def failing_at_level_1(task):
        if task.level == 1:
            raise ProjectionError("no convergence\nin 50 iterations")
        return run_task(task)
    monkeypatch.setattr(convergence, "run_task", failing_at_level_1)
    result = CliRunner().invoke(main, ["convergence", str(CASES / "corridor-wall"), "--levels", "3", "--serial",
                                       "--set", "time.end=0.2", "--out", str(tmp_path), "-q"])
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    reason = "default, level 1 (corridor.msh refine 1): ProjectionError: no convergence in 50 iterations"
    assert result.stderr == (f"femcrowd: error: 1 of 3 runs failed ({reason}); finished levels 0, 2 (of 0-2) kept "
                             f"in {tmp_path}/convergence.csv and convergence.md\n")
    with open(tmp_path / "convergence.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["level"]) for r in rows] == [0, 2]
    assert 0 < float(rows[1]["l1"]) < float(rows[0]["l1"]) < 0.05   # measured against the exact solution
    report = (tmp_path / "convergence.md").read_text()
    assert "**1 failed: 2 of 3 runs finished (levels 0, 2)**" in report and f"- failed: {reason}\n" in report
    assert report in result.stdout and not (tmp_path / "error_vs_h.png").exists()
