"""What a new user met, each fixed: relative output paths, the stress matrix from the repository root,
verbose and quiet output, re-runs next to pictures, the initial row of history.csv, studies that step
like `femcrowd run`."""

import json
import shutil

import numpy as np
from click.testing import CliRunner

from femcrowd import load_case, run
from femcrowd.cli import main
from femcrowd.driver.reading import read_history
from femcrowd.studies.convergence import plan_study, run_task

from ..support import CASES, MESHES


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def copy_scenes(tmp_path):
    """cases/ and meshes/ of the repository in tmp_path (so that nothing is written into the checkout)."""
    shutil.copytree(CASES, tmp_path / "cases", ignore=shutil.ignore_patterns("output"))
    shutil.copytree(MESHES, tmp_path / "meshes")
    return tmp_path


def test_relative_out_is_relative_to_the_current_directory(tmp_path, monkeypatch):
    """run, compare and convergence: a relative --out is taken from where the command is typed."""
    root = copy_scenes(tmp_path)
    monkeypatch.chdir(root)
    result = invoke("run", "cases/room", "--out", "results/room", "-q", "--set", "time.end=0.5")
    assert result.exit_code == 0, result.output
    assert (root / "results" / "room" / "summary.json").is_file()
    result = invoke("convergence", "cases/corridor-wall", "--levels", "2", "--serial", "--out", "results/conv",
                    "--set", "time.end=0.2")
    assert result.exit_code == 0, result.output
    assert (root / "results" / "conv" / "convergence.csv").is_file()
    result = invoke("compare", "cases/narrow-door", "--out", "results/compare", "-q", "--set", "time.end=0.5")
    assert result.exit_code == 0, result.output
    assert (root / "results" / "compare" / "comparison.csv").is_file()
    assert not list((root / "cases").rglob("results"))  # nothing under the case directories


def test_output_dir_of_the_case_is_relative_to_the_case_file(tmp_path, monkeypatch):
    root = copy_scenes(tmp_path)
    monkeypatch.chdir(tmp_path / "meshes")  # anywhere else
    result = invoke("run", root / "cases" / "room", "-q", "--set", "time.end=0.5")
    assert result.exit_code == 0, result.output
    assert (root / "cases" / "room" / "output" / "summary.json").is_file()


def test_stress_without_out_from_the_repository_root(tmp_path, monkeypatch):
    """The README's `femcrowd stress` (here two scenes): runs and tables in ./stress-output, the case
    directories untouched."""
    root = copy_scenes(tmp_path)
    before = sorted(p.relative_to(root) for p in (root / "cases").rglob("*"))
    monkeypatch.chdir(root)
    result = invoke("stress", "--only", "u-zero", "--only", "expanding-block")
    assert result.exit_code == 0, result.output
    assert "2/2 scenes pass" in result.output
    assert (root / "stress-output" / "stress.md").is_file()
    assert (root / "stress-output" / "u-zero" / "history.csv").is_file()
    assert sorted(p.relative_to(root) for p in (root / "cases").rglob("*")) == before


def test_verbose_logs_solver_details_and_quiet_plot_prints_one_line(tmp_path):
    out = tmp_path / "room"
    quiet = invoke("run", CASES / "room", "--out", out, "-q", "--set", "time.end=1")
    verbose = invoke("-v", "run", CASES / "room", "--out", tmp_path / "room2", "-q", "--set", "time.end=1")
    assert quiet.exit_code == verbose.exit_code == 0
    assert quiet.stderr == ""
    assert "set up" in verbose.stderr and "t = 1 s" in verbose.stderr and "max_density" in verbose.stderr
    result = invoke("plot", out, "-q", "--no-animation")
    assert result.exit_code == 0 and result.output.count("\n") == 1, result.output


def test_a_new_run_keeps_the_pictures_and_says_what_it_replaces(tmp_path):
    out = tmp_path / "room"
    assert invoke("run", CASES / "room", "--out", out, "-q", "--set", "time.end=1").exit_code == 0
    assert invoke("plot", out, "-q", "--no-animation").exit_code == 0
    pictures = sorted(p.name for p in (out / "plots").iterdir())
    assert "curves.png" in pictures
    again = invoke("run", CASES / "room", "--out", out, "-q", "--set", "time.end=0.5")
    assert again.exit_code == 0
    assert "replacing the earlier run" in again.stderr and "plots/ are kept" in again.stderr
    assert sorted(p.name for p in (out / "plots").iterdir()) == pictures
    assert json.loads((out / "summary.json").read_text())["final_time"] == 0.5
    assert len(list(out.glob("solution_*.vtu"))) == 2  # the old frames are gone


def test_history_starts_with_the_initial_state(tmp_path):
    summary = run(load_case(CASES / "room", ["time.end=0.5"]), tmp_path).summary
    h = read_history(tmp_path / "history.csv")
    assert h["time"][0] == 0 and h["dt"][0] == 0 and h["evacuated"][0] == 0
    assert h["mass"][0] == summary["initial_mass"] and len(h["time"]) == summary["steps"] + 1


def test_a_study_takes_the_steps_of_femcrowd_run(tmp_path):
    """The same time steps (landing on the frame times) as `femcrowd run` of that level."""
    base, exact, tasks = plan_study(CASES / "corridor-wall", 2)
    for task in tasks:
        state_steps = run_task(task)["rows"][-1]["steps"]
        summary = run(load_case(task.case_dir, task.overrides), tmp_path / str(task.level)).summary
        assert state_steps == summary["steps"]
        h = read_history(tmp_path / str(task.level) / "history.csv")
        assert np.all(h["dt"][1:] > 1e-12)  # no step of round-off length before a frame time


def test_the_case_of_an_output_directory_runs_the_same_case(tmp_path):
    """The case.toml a run writes (defaults filled, --set applied, paths from the output directory) runs again on
    its own, in another directory: the same history (but the wall time of the steps)."""
    first, again = tmp_path / "first" / "out", tmp_path / "again"
    args = ["--set", "time.end=3", "--set", "velocity.speed=1.1", "--set", 'boundary.open={door=[[0, 2], [2.5, inf]]}']
    assert CliRunner().invoke(main, ["run", str(CASES / "entrance"), "--out", str(first), "-q", *args]).exit_code == 0
    result = CliRunner().invoke(main, ["run", str(first), "--out", str(again), "-q"])
    assert result.exit_code == 0, result.output
    a, b = read_history(first / "history.csv"), read_history(again / "history.csv")
    assert set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a if k != "step_seconds")
    assert load_case(first).config["velocity"]["speed"] == 1.1
