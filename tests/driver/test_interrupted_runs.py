"""Ctrl-C or a crash in the middle of a run: what was written stays readable and summary.json says so."""

import csv
import json
import signal
import subprocess
import time

import meshio
import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd.cli import main
from femcrowd.driver.reading import read_pvd
from femcrowd.macro import MacroSolver

from ..support import CASES, FEMCROWD

CASE = CASES / "stress" / "head-on"   # frames every 0.25 s, ~40 steps per frame


def fail_after(monkeypatch, steps, error):
    original = MacroSolver.step
    done = []

    def step(self, state, until=np.inf):
        if len(done) == steps:
            raise error
        done.append(1)
        return original(self, state, until)
    monkeypatch.setattr(MacroSolver, "step", step)


def check_readable(out, steps):
    """history.csv has a row for the initial state and one per step; every frame of solution.pvd
    reads back, and the mass of the last one equals the history's mass at its time."""
    with open(out / "history.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == steps + 1 and float(rows[0]["time"]) == 0
    times = np.array([float(r["time"]) for r in rows])
    assert np.all(np.diff(times) > 0)
    frames = read_pvd(out / "solution.pvd")
    assert len(frames) >= 2
    for t, name in frames:
        mesh = meshio.read(out / name)
        assert np.isfinite(mesh.cell_data["density"][0]).all()
    x = mesh.points[mesh.cells[0].data]
    u, v = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    row = rows[int(np.argmin(np.abs(times - frames[-1][0])))]
    assert area @ mesh.cell_data["density"][0] == pytest.approx(float(row["mass"]), rel=1e-12)
    return frames


def test_ctrl_c_mid_run(tmp_path, monkeypatch):
    fail_after(monkeypatch, 100, KeyboardInterrupt)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(CASE), "--out", str(out), "-q"])
    assert result.exit_code == 130
    assert "interrupted" in result.stderr and "Traceback" not in result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps"] == 100
    frames = check_readable(out, 100)
    assert frames[-1][0] <= summary["final_time"] < 1.5


def test_crash_mid_run(tmp_path, monkeypatch):
    fail_after(monkeypatch, 60, RuntimeError("solver exploded"))
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(CASE), "--out", str(out), "-q"])
    assert isinstance(result.exception, RuntimeError)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed: RuntimeError: solver exploded" and summary["steps"] == 60
    check_readable(out, 60)
    monkeypatch.undo()  # the directory is femcrowd's: a new run may replace it without --force
    result = CliRunner().invoke(main, ["run", str(CASE), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    assert json.loads((out / "summary.json").read_text())["status"] == "completed"


def test_sigint_to_a_running_process(tmp_path):
    """A real Ctrl-C (SIGINT) to `femcrowd run`: exit code 130, one line on stderr, no traceback."""
    out = tmp_path / "out"
    # A terminal's Ctrl-C reaches a process whose SIGINT has the default disposition; a child
    # inherits "ignored" from its parent (some earlier test in a full run leaves it so), and
    # Python then installs no KeyboardInterrupt handler: reset it in the child.
    proc = subprocess.Popen([str(FEMCROWD), "run", str(CASE), "--out", str(out), "-q", "--set", "time.end=1e4"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        history = out / "history.csv"
        if history.is_file() and len(history.read_text().splitlines()) > 100:
            break
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=300)  # generous: only a loaded machine is slow here
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1
    assert "interrupted" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps"] >= 100  # header, t = 0, 100 steps
    check_readable(out, summary["steps"])
