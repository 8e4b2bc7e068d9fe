"""Micro cases through the case system, and the micro/macro comparison on the narrow door."""

import json

import numpy as np
import pytest
import pyvista
from click.testing import CliRunner

from femcrowd import load_case, run
from femcrowd.cli import main
from femcrowd.driver.reading import read_history
from femcrowd.errors import InputError, RunFailed
from femcrowd.micro import MicroSimulation
from femcrowd.studies.compare import compare

from ..support import CASES, assert_phases_within_wall


def run_micro(case, out):
    return run(case, out).summary


def test_shipped_micro_case_outputs_and_invariants(tmp_path):
    """The whole shipped micro case: no overlap beyond 1e-9 r at any step, no disc outside."""
    case = load_case(CASES / "narrow-door-micro", ["output.every=10"])
    summary = run_micro(case, tmp_path)
    assert summary["status"] == "completed" and summary["initial_count"] > 50
    h = read_history(tmp_path / "history.csv")
    assert {"time", "dt", "count", "evacuated", "contacts", "max_overlap", "solver_iterations",
            "step_seconds"} <= set(h)
    assert np.all(h["count"] + h["evacuated"] == summary["initial_count"])   # nobody lost
    assert np.all(np.diff(h["count"]) <= 0)
    assert h["max_overlap"].max() <= 1e-9 * 0.2
    assert summary["discs_outside"] == 0
    timing = dict(summary["timing"])
    assert_phases_within_wall(timing)
    assert h["contacts"].max() > 0                                            # a real jam forms
    # frames every 10 s, the last one at the end of the run: t = 40 s, or earlier if the
    # arch at the door gives way (frictionless discs: whether a marginal arch holds depends
    # on round-off, e.g. the factorisation's ordering, so both outcomes are valid)
    reader = pyvista.get_reader(str(tmp_path / "discs.pvd"))
    end = h["time"][-1]
    assert np.allclose(reader.time_values, [t for t in (0, 10, 20, 30) if t < end - 1e-9] + [min(end, 40.0)])
    reader.set_active_time_value(reader.time_values[-1])
    cloud = reader.read()[0]
    assert cloud.n_points == h["count"][-1]
    assert {"radius", "velocity", "pressure"} <= set(cloud.point_data.keys())
    assert np.all(np.asarray(cloud.point_data["pressure"]) >= 0)


def test_explicit_discs_from_csv(tmp_path):
    """Two discs in a row walking to the door: positions from the CSV, both leave."""
    (tmp_path / "discs.csv").write_text("x,y,r\n6.0,2.5,0.2\n5.0,2.5,0.2\n")
    case_dir = tmp_path / "case"
    case_dir.mkdir()
    mesh = (CASES.parent / "meshes" / "room_narrow_door.msh").resolve()
    (case_dir / "case.toml").write_text(
        f'[mesh]\nfile = "{mesh}"\n[boundary]\nexits = ["exit"]\n[model]\ntype = "micro"\n'
        f'[micro]\npositions = "../discs.csv"\n[time]\nend = 10.0\n')
    summary = run_micro(load_case(case_dir), tmp_path / "out")
    assert summary["initial_count"] == 2 and summary["evacuated"] == 2
    assert summary["evacuation_time"] == pytest.approx(3.0 + 0.2, abs=0.3)  # 3 m at speed 1 (+ one step)


def discs_csv_case(folder, rows: str, extra: str = "") -> None:
    """A disc case in `folder` on the narrow-door room, its discs the rows x,y,r of discs.csv."""
    (folder / "discs.csv").write_text("x,y,r\n" + rows)
    mesh = (CASES.parent / "meshes" / "room_narrow_door.msh").resolve()
    (folder / "case.toml").write_text(
        f'[mesh]\nfile = "{mesh}"\n[boundary]\nexits = ["exit"]\n[model]\ntype = "micro"\n'
        f'[micro]\npositions = "discs.csv"\n' + extra)


def test_csv_with_a_disc_outside_is_refused(tmp_path):
    discs_csv_case(tmp_path, "60.0,2.5,0.2\n")
    with pytest.raises(InputError, match="micro.positions.*outside the domain"):
        run_micro(load_case(tmp_path), tmp_path / "out")
    result = CliRunner().invoke(main, ["run", str(tmp_path), "--out", str(tmp_path / "o2")])
    assert result.exit_code == 2 and "Traceback" not in result.output


@pytest.mark.parametrize("rows, words", [
    ("1,1,0.2\n# a comment\n1.3,1,0.2\n", "discs of line 2 (x = 1, y = 1, r = 0.2) and line 4 (x = 1.3, y = 1, "
                                           "r = 0.2) overlap by 0.1 m"),
    ("1,1,0.2\n0.1,3,0.2\n", "disc of line 3 (x = 0.1, y = 3, r = 0.2) crosses a wall by 0.1 m"),
    ("1,1,0.2\n2,2,100\n", "disc of line 3 (x = 2, y = 2, r = 100) crosses a wall by 98 m"),
    ("1,1,0.2\n20,3,0.2\n", "1 disc centres lie outside the domain, the first at line 3 (x = 20, y = 3, r = 0.2)"),
], ids=["overlap", "wall", "radius-100", "outside"])
def test_csv_discs_that_overlap_or_cross_a_wall_are_refused(tmp_path, rows, words):
    """One line naming the case, the CSV, the line and the disc; exit 2, before anything is written (a disc of
    radius 100 was a traceback after the first frames; overlaps ran with 'max overlap 2.0 r')."""
    discs_csv_case(tmp_path, rows)
    result = CliRunner().invoke(main, ["run", str(tmp_path), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    assert "micro.positions = 'discs.csv'" in result.stderr and words in result.stderr, result.stderr
    assert not (tmp_path / "out").exists()


def test_discs_touching_each_other_and_a_wall_are_accepted(tmp_path):
    """Touching (gap 0 up to round-off) is not overlapping: discs at x = 0.2 (on the wall x = 0) and 0.6."""
    discs_csv_case(tmp_path, "0.2,1,0.2\n0.6,1,0.2\n", "[time]\nend = 0.2\n")
    assert run_micro(load_case(tmp_path), tmp_path / "out")["initial_count"] == 2


def test_compare_narrow_door_macro_evacuates_faster(tmp_path):
    """The findings of Maury et al. (2011) on a narrow door: the discs jam, the macro crowd leaves faster."""
    case = load_case(CASES / "narrow-door", ["time.end=12", "output.every=1"])
    result = compare(case, tmp_path, quiet=True, pictures=2)
    rows = result["rows"]
    assert rows[0]["macro_inside"] == pytest.approx(rows[0]["micro_inside"])   # same crowd
    assert result["macro"]["evacuation_time"] is not None and result["macro"]["evacuation_time"] < 12
    # jammed at the door: not one sampling's outcome, a margin that holds over all (seeds 1 to 5 of README.md
    # keep 54-58 of the 72 discs inside at 10 s, 31-44 at 20 s)
    assert rows[-1]["micro_inside"] > 0.25 * rows[0]["micro_inside"]
    assert all(r["macro_inside"] <= r["micro_inside"] + 1e-9 for r in rows)
    w2 = [r["w2"] for r in rows if r["macro_inside"] > 1 and r["micro_inside"] > 0]
    assert w2 and all(np.isfinite(w2)) and w2[0] < 0.5                        # same initial crowd
    for name in ("comparison.csv", "evacuation.png", "macro/solution.pvd", "micro/discs.pvd"):
        assert (tmp_path / name).is_file()
    assert len(list(tmp_path.glob("side_by_side_t*.png"))) == 2


def test_compare_reads_the_empty_disc_frames_of_a_finished_micro_run(tmp_path):
    """Frames after the last disc left have no points (meshio cannot decode them): the comparison
    reads them as an empty crowd, counts 0 people inside and writes its report."""
    case = load_case(CASES / "narrow-door", ["time.end=6", "output.every=1", "initial.density=0.3 * (x > 7)"])
    result = compare(case, tmp_path, quiet=True, pictures=2)
    rows = result["rows"]
    assert rows[0]["micro_inside"] > 0 and rows[-1]["micro_inside"] == 0   # all out before t = 6
    assert rows[-1]["macro_inside"] == pytest.approx(0.0, abs=1e-6)
    assert (tmp_path / "comparison.csv").is_file()


def test_discs_behind_a_door_that_closes_stand_still(tmp_path):
    """cases/narrow-door-micro with its exit closed at 6 s: the discs left inside stay (U = 0, the projection
    with nothing to do but undo round-off overlaps), the run completes and every disc is counted."""
    case = load_case(CASES / "narrow-door-micro", ["boundary.open={exit=[[0, 6]]}", "time.end=8"])
    summary = run_micro(case, tmp_path)
    assert summary["status"] == "completed" and summary["final_count"] > 0
    assert summary["initial_count"] == summary["final_count"] + summary["evacuated"]


def test_a_disc_through_a_wall_fails_the_run_in_one_line(tmp_path, monkeypatch):
    """A step that leaves a disc outside the domain, not through the exit (here the third step carries disc 0
    50 m beyond the wall x = 0, as a step of a perturbation of 1e12 m/s did), is an error, never a disc "left
    inside": exit code 1, one line naming the case, the key and where the disc went; the summary says failed and
    the history keeps the steps before."""
    real = MicroSimulation.step

    def step(sim):
        info = real(sim)
        if info.step == 3:
            info.q[0] = (-50.0, 1.0)
        return info

    monkeypatch.setattr(MicroSimulation, "step", step)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(CASES / "narrow-door-micro"), "-q", "--out", str(out),
                                       "--set", "micro.fluctuation=0.5", "--set", "time.end=1"])
    assert result.exit_code == 1 and result.stdout == "" and "Traceback" not in result.stderr, result.output
    [line] = result.stderr.splitlines()
    assert line.startswith(f"femcrowd: error: {CASES / 'narrow-door-micro' / 'case.toml'}: micro.fluctuation = 0.5: "
                           "1 disc(s) left the domain through a wall in the step to t = 0.3 s")
    assert "the first to (-50, 1)" in line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"].startswith("failed: RunFailed: ") and summary["discs_outside"] == 0
    assert read_history(out / "history.csv")["time"][-1] == pytest.approx(0.2)


def test_moves_no_candidate_list_covers_fail_the_run_in_one_line():
    """micro.fluctuation = 1e300 (past the limits, with limits=None as --no-limits): velocities overflow and no
    candidate list covers the step; RunFailed naming the key, not a RuntimeError."""
    case = load_case(CASES / "narrow-door-micro", {"micro.fluctuation": 1e300, "time.end": 1})
    with pytest.raises(RunFailed) as failed, np.errstate(all="ignore"):
        run(case, files=False, limits=None)
    assert failed.value.key == "micro.fluctuation" and "could not cover the moves" in failed.value.message
