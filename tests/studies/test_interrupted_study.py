"""Ctrl-C during a convergence study: the finished levels are kept (report written), one line says which
and where, no traceback from the dask workers, exit code 130 as for `femcrowd run`."""

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
                             "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
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
    deadline = time.monotonic() + 10   # no worker left behind
    while time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.2)
    else:
        pytest.fail("processes of the study's group still alive 10 s after it ended")


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
