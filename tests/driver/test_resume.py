"""Runs that resume: a real Ctrl-C at a random step, then `femcrowd run --resume`, gives the final frame,
history and summary of the uninterrupted run (to round-off); a corrupted or foreign checkpoint is refused
without touching the output."""

import json
import random
import signal
import subprocess
import time

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd.cli import main
from femcrowd.driver.reading import read_frame, read_history, read_pvd

from ..support import CASES, FEMCROWD

CASE = CASES / "stress" / "head-on"  # 258 steps, a frame every 0.25 s, collisions: the projection at work
#: how the solver got there (not the state): a resumed run starts its projection cold, without a warm start
SOLVER_PATH = {"active_set_iterations", "step_seconds", "linear_residual", "complementarity"}


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def snapshot(directory):
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(directory.iterdir())}


def same_run(a, b, rtol=1e-10):
    """The histories, the frame times and the last frames of two output directories agree to round-off."""
    ha, hb = read_history(a / "history.csv"), read_history(b / "history.csv")
    assert len(ha["time"]) == len(hb["time"])
    for column in ha:
        if column not in SOLVER_PATH:
            scale = max(np.abs(ha[column]).max(), 1e-300)
            assert np.abs(ha[column] - hb[column]).max() <= rtol * scale + 1e-14, column
    fa, fb = read_pvd(a / "solution.pvd"), read_pvd(b / "solution.pvd")
    assert [t for t, _ in fa] == [t for t, _ in fb]
    last_a, last_b = read_frame(a / fa[-1][1]).cell_data, read_frame(b / fb[-1][1]).cell_data
    for name in ("density", "pressure"):
        assert np.allclose(last_a[name][0], last_b[name][0], rtol=0, atol=rtol * max(last_b[name][0].max(), 1))
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert sa["status"] == sb["status"] == "completed" and sa["steps"] == sb["steps"]
    assert sa["evacuated"] == pytest.approx(sb["evacuated"], rel=rtol, abs=1e-14)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("whole") / "out"
    assert invoke("run", CASE, "--out", out, "-q").exit_code == 0
    return out


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["INT", "TERM", "HUP"])
def test_a_signal_at_a_random_step_then_resume(tmp_path, uninterrupted, stop):
    """Ctrl-C, kill or a closed terminal: the step under way ends, the run is checkpointed and says so."""
    out = tmp_path / "out"
    stop_after = random.Random().randint(20, 200)  # history rows before the signal
    proc = subprocess.Popen([str(FEMCROWD), "run", str(CASE), "--out", str(out), "-q"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        history = out / "history.csv"
        if history.is_file() and len(history.read_text().splitlines()) > stop_after:
            break
        time.sleep(0.01)
    proc.send_signal(stop)
    _, stderr = proc.communicate(timeout=300)
    if proc.returncode == 0:
        pytest.skip(f"the run ended before the signal (after {stop_after} rows): nothing to resume")
    assert proc.returncode == 130, stderr
    interrupted = json.loads((out / "summary.json").read_text())
    assert interrupted["status"] == "interrupted"
    assert (out / "checkpoint.npz").is_file()
    result = invoke("run", CASE, "--out", out, "-q", "--resume")
    assert result.exit_code == 0, result.output
    same_run(out, uninterrupted)


def test_resume_continues_a_run_to_a_later_end(tmp_path, uninterrupted):
    """Ended at a frame time (0.5 s), then continued to the case's 1.5 s: the steps of one run to 1.5 s."""
    out = tmp_path / "out"
    assert invoke("run", CASE, "--out", out, "-q", "--set", "time.end=0.5").exit_code == 0
    result = invoke("run", CASE, "--out", out, "-q", "--resume")  # time.end = 1.5 of the case
    assert result.exit_code == 0, result.output
    same_run(out, uninterrupted)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["case"]["time"]["end"] == 1.5


def test_resume_after_a_run_that_ended_between_frames(tmp_path, uninterrupted):
    """Ended at 0.6 s, between the frames at 0.5 and 0.75 s (its last step cut short to land there), then continued
    to the case's 1.5 s: the steps of one run to 1.5 s (before, 1.4e-5 apart in density: the run went on from the
    cut step)."""
    out = tmp_path / "out"
    assert invoke("run", CASE, "--out", out, "-q", "--set", "time.end=0.6").exit_code == 0
    assert read_history(out / "history.csv")["time"][-1] == 0.6
    result = invoke("run", CASE, "--out", out, "-q", "--resume")
    assert result.exit_code == 0, result.output
    same_run(out, uninterrupted, rtol=1e-12)


def disc_run_resumed(tmp_path, first_end, end, *settings):
    """(uninterrupted, resumed) output directories of cases/narrow-door-micro with `settings`: one run to `end`,
    one to `first_end` continued to `end` with --resume."""
    whole, part = tmp_path / "whole", tmp_path / "part"
    case, options = CASES / "narrow-door-micro", [s for setting in settings for s in ("--set", setting)]
    assert invoke("run", case, "--out", whole, "-q", *options, "--set", f"time.end={end}").exit_code == 0
    assert invoke("run", case, "--out", part, "-q", *options, "--set", f"time.end={first_end}").exit_code == 0
    assert invoke("run", case, "--out", part, "-q", *options, "--set", f"time.end={end}", "--resume").exit_code == 0
    return whole, part


def same_disc_run(whole, part):
    """The history (but the seconds), the frames, the discs and their trajectories of two runs are the same, bit
    for bit."""
    ha, hb = read_history(whole / "history.csv"), read_history(part / "history.csv")
    assert ha.keys() == hb.keys()
    assert [k for k in ha if k != "step_seconds" and not np.array_equal(ha[k], hb[k])] == []
    fa, fb = read_pvd(whole / "discs.pvd"), read_pvd(part / "discs.pvd")
    assert [t for t, _ in fa] == [t for t, _ in fb]
    a, b = (read_frame(d / f[-1][1]) for d, f in ((whole, fa), (part, fb)))
    assert np.array_equal(a.points, b.points)
    assert (whole / "trajectories.txt").read_text() == (part / "trajectories.txt").read_text()


@pytest.mark.parametrize("first_end", [1.5, 1.55], ids=["at-a-frame", "between-frames"])
def test_disc_runs_resume_bit_for_bit(tmp_path, first_end):
    """A disc run to 1.5 s (a frame time) or 1.55 s (between frames), continued to 3 s: the uninterrupted run."""
    same_disc_run(*disc_run_resumed(tmp_path, first_end, 3))


def test_a_disc_run_resumes_while_a_door_is_held_open(tmp_path):
    """The exit is to close at 6.15 s, a disc stands in its doorway until 6.25 s (tests/micro/test_closing_doors.py):
    a checkpoint at 6.2 s keeps the door open, the resumed run closes it at 6.25 s, as the uninterrupted one."""
    whole, part = disc_run_resumed(tmp_path, 6.2, 6.5, "boundary.open={exit=[[0, 6.15]]}", "output.every=0.1",
                                   "velocity.type=field", "velocity.ux=1 - 2 * (t >= 6.15)")
    same_disc_run(whole, part)
    assert read_history(part / "history.csv")["overlap_r"].max() <= 1e-9


def drop_array(path, name):
    """The checkpoint as a hand-made one might be: a valid archive with one array left out."""
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != name}
    with open(path, "wb") as f:
        np.savez(f, **arrays)


@pytest.mark.parametrize("spoil, words", [
    (lambda out: (out / "checkpoint.npz").write_bytes((out / "checkpoint.npz").read_bytes()[:200]), "corrupted"),
    (lambda out: (out / "checkpoint.npz").unlink(), "no checkpoint"),
    (lambda out: drop_array(out / "checkpoint.npz", "state/rho"), "do not fit this run"),
    (lambda out: drop_array(out / "checkpoint.npz", "row/mass"), "do not fit this run"),
])
def test_a_bad_checkpoint_is_refused_and_nothing_changes(tmp_path, spoil, words):
    out = tmp_path / "out"
    assert invoke("run", CASE, "--out", out, "-q", "--set", "time.end=0.5").exit_code == 0
    spoil(out)
    before = snapshot(out)
    result = invoke("run", CASE, "--out", out, "-q", "--resume")
    assert result.exit_code == 2 and result.stderr.count("\n") == 1 and words in result.stderr, result.output
    assert "--resume" in result.stderr and snapshot(out) == before


def test_resume_to_an_earlier_end_is_refused(tmp_path):
    """A checkpoint at 0.5 s, resumed with time.end = 0.25: one line naming the key, exit 2, nothing touched."""
    out = tmp_path / "out"
    assert invoke("run", CASE, "--out", out, "-q", "--set", "time.end=0.5").exit_code == 0
    before = snapshot(out)
    result = invoke("run", CASE, "--out", out, "-q", "--resume", "--set", "time.end=0.25")
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    assert "time.end = 0.25" in result.stderr and "before the time of the checkpoint" in result.stderr
    assert snapshot(out) == before


def test_a_checkpoint_of_another_case_or_mesh_is_refused(tmp_path):
    case = tmp_path / "case"
    case.mkdir()
    mesh = tmp_path / "headon.msh"
    mesh.write_bytes((CASES.parent / "meshes" / "stress" / "headon.msh").read_bytes())
    (case / "case.toml").write_text((CASE / "case.toml").read_text().replace("../../../meshes/stress/", "../"))
    out = tmp_path / "out"
    assert invoke("run", case, "--out", out, "-q", "--set", "time.end=0.5").exit_code == 0
    before = snapshot(out)
    for other in ("initial.density=0.5", "mesh.refine=1"):
        result = invoke("run", case, "--out", out, "-q", "--resume", "--set", other)
        assert result.exit_code == 2 and "another case" in result.stderr, result.output
    mesh.write_bytes(mesh.read_bytes() + b"\n")  # the same name, another file
    result = invoke("run", case, "--out", out, "-q", "--resume")
    assert result.exit_code == 2 and "another mesh" in result.stderr, result.output
    assert snapshot(out) == before


@pytest.mark.parametrize("model, route", [("macro", "shortest"), ("micro", "shortest"), ("macro", "congestion"),
                                          ("micro", "congestion")])
def test_arrivals_doors_and_measurements_resume(tmp_path, model, route):
    """cases/entrance (a source, a door schedule, lines and an area): stopped at 12 s (door closed), then
    continued to 20 s, it gives the uninterrupted run's history, measurements (and disc trajectories); with the
    route choice too (its routes, re-solved every 0.7 s, in the checkpoint)."""
    whole, part = tmp_path / "whole", tmp_path / "part"
    case = CASES / "entrance"
    common = ["-q", "--set", f'model.type="{model}"', "--set", f'velocity.route="{route}"',
              "--set", "velocity.route_every=0.7"]
    assert invoke("run", case, "--out", whole, "--set", "time.end=20", *common).exit_code == 0
    assert invoke("run", case, "--out", part, "--set", "time.end=12", *common).exit_code == 0
    assert invoke("run", case, "--out", part, "--set", "time.end=20", "--resume", *common).exit_code == 0
    for name in ("history.csv", "measurements.csv"):
        a, b = read_history(whole / name), read_history(part / name)
        assert set(a) == set(b) and len(a["time"]) == len(b["time"])
        for column in set(a) - SOLVER_PATH - {"solver_iterations", "kkt", "gap", "change"}:
            assert np.allclose(a[column], b[column], rtol=1e-9, atol=1e-9), (name, column)
    if model == "micro":
        assert (whole / "trajectories.txt").read_text() == (part / "trajectories.txt").read_text()
