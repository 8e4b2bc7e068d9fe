"""The end of every run says how many people are left and why (driver/remaining.py), in its last lines and in
summary.json; people who can never leave are warned of; the progress bar ends when the crowd is out."""

import io
import json
from functools import partial

import numpy as np
import pytest
from click.testing import CliRunner
from tqdm import tqdm

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.driver import loop

from ..mesh.test_checks import square, write_msh
from ..support import CASES

CASE = """title = "rooms of 1 x 1 m, an exit on the left side of the first"

[mesh]
file = "rooms.msh"

[boundary]
exits = ["left"]

[initial]
density = 0.5

[micro]
radius = 0.06

[time]
end = {end}

[output]
every = {end}
"""


def rooms(tmp_path, count=1, end=4.0):
    """A case of `count` unit squares side by side, 1 m apart (disconnected): the first has the exit."""
    parts = [square(x0=2.0 * k) for k in range(count)]
    offsets = np.cumsum([0] + [len(points) for points, _, _ in parts])
    points = np.vstack([points for points, _, _ in parts])
    triangles = np.vstack([t + o for (_, t, _), o in zip(parts, offsets)])
    walls = [tuple(np.add(pair, o)) for (_, _, groups), o in zip(parts, offsets)
             for pair in groups["wall"] + (groups["left"] if o else [])]
    write_msh(tmp_path / "rooms.msh", points, triangles, {"left": parts[0][2]["left"], "wall": walls})
    (tmp_path / "case.toml").write_text(CASE.format(end=end))
    return tmp_path


def run(case_dir, out, *overrides):
    """femcrowd run into out: its stdout, stderr and summary.json."""
    result = CliRunner().invoke(main, ["run", str(case_dir), "--out", str(out), "-q", *overrides])
    assert result.exit_code == 0, result.output
    return result.stdout, result.stderr, json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("model", ["macro", "micro"])
def test_a_room_without_exit(tmp_path, model):
    """Two rooms, only the first with an exit: a warning at the start with the people of the second, who are
    left at the end for want of an exit; the first room empties."""
    stdout, stderr, summary = run(rooms(tmp_path, 2), tmp_path / "out", "--set", f"model.type={model}")
    remaining = summary["remaining"]
    assert remaining["reason"] == "no reachable exit"
    trapped = remaining["people"]
    if model == "macro":
        assert trapped == pytest.approx(0.5, rel=1e-9)   # density 0.5 on 1 m^2, rho_max 1; the first room empty
    else:
        assert summary["initial_count"] > trapped > 0.3 * summary["initial_count"] and isinstance(trapped, int)
    assert remaining["by_reason"] == {"no reachable exit": pytest.approx(trapped)}
    assert remaining["per_population"] == {"crowd": pytest.approx(trapped)}
    people = f"{trapped:.4g} m^2 at rho_max" if model == "macro" else f"{trapped} people"   # rho_max = 1
    assert ("1 of the 2 regions of the mesh rooms.msh have no exit open during the run (one at (2." in stderr
            and f"{people} can never leave" in stderr), stderr
    assert f"left inside: {people} (no reachable exit)\n" in stdout
    assert summary["final_time"] == 4.0 and summary["evacuation_time"] is None


def test_a_door_that_closes_for_good(tmp_path):
    """cases/room with its door open for 2 s only: nobody reaches it, everybody is left behind it."""
    stdout, stderr, summary = run(CASES / "room", tmp_path / "out", "--set", "boundary.open={exit=[[0,2]]}",
                                  "--set", "time.end=4")
    remaining = summary["remaining"]
    assert remaining["reason"] == "closed door" and summary["evacuated"] < 1e-12
    assert remaining["people"] == pytest.approx(summary["initial_mass"], rel=1e-12)
    assert remaining["people"] == pytest.approx(summary["final_mass"], rel=1e-12)
    people = f"{remaining['people']:.4g} m^2 at rho_max"   # cases/room: rho_max = 1
    assert f"{people} can never leave (t = 4 s): {people} behind exits closed for good (exit)" in stderr
    assert f"left inside: {people} (closed door)\n" in stdout


@pytest.mark.parametrize("model", ["macro", "micro"])
def test_a_run_stopped_by_time_end(tmp_path, model):
    case = load_case(rooms(tmp_path, 1, end=0.3), [f"model.type={model}"])
    summary = Simulation(case).run().summary
    remaining = summary["remaining"]
    left = summary["final_mass"] if model == "macro" else summary["final_count"]
    assert remaining["reason"] == "time.end" and remaining["people"] == pytest.approx(left, rel=1e-12) and left > 0
    assert summary["final_time"] == pytest.approx(0.3)


@pytest.mark.parametrize("model", ["macro", "micro"])
def test_an_emptied_run_ends_when_the_crowd_is_out(tmp_path, monkeypatch, model):
    """Nobody left (at most time.empty_fraction of the crowd), and the run, its summary and its progress bar end
    at the evacuation time, not at time.end."""
    bars = []

    class Bar(tqdm):
        def close(self):
            bars.append((self.n, self.total))
            super().close()

    monkeypatch.setattr(loop, "tqdm", partial(Bar, file=io.StringIO()))
    case = load_case(rooms(tmp_path, 1, end=20.0), [f"model.type={model}"])
    summary = Simulation(case).run(quiet=False).summary
    remaining = summary["remaining"]
    assert remaining["reason"] == "evacuated" and remaining["by_reason"] == {}
    if model == "macro":
        assert remaining["people"] <= 1e-4 * summary["initial_mass"]
        assert remaining["people"] == pytest.approx(summary["final_mass"])
    else:
        assert remaining["people"] == 0
    end = summary["evacuation_time"]
    assert end is not None and end < 5.0 and summary["final_time"] == end
    n, total = bars[0]   # (tqdm's __del__ closes again)
    assert total == end and n == pytest.approx(end, rel=1e-12)


def test_the_reason_agrees_with_the_stop_at_the_threshold():
    """A run stopped because at most time.empty_fraction of its crowd is inside says "evacuated", even when the
    people left equal that threshold up to round-off: the reason is the model's own verdict, not a second sum.
    (empty_fraction = 1, refused in a case file, is set here through the API: the first step stops the run.)"""
    case = load_case(CASES / "room", ["time.end=1"])
    case.config["time"]["empty_fraction"] = 1.0
    summary = Simulation(case).run().summary
    assert summary["status"] == "completed" and summary["final_time"] < 1
    assert summary["evacuation_time"] == summary["final_time"]
    assert summary["remaining"]["reason"] == "evacuated"
