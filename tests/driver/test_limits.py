"""Runaway runs (issue 24): a run that plans too many frames or steps, too much memory or disk is refused with one
line naming the key, before the mesh is refined, the discs sampled or the output directory touched; femcrowd
info prints the same plan; a step that cannot advance t stops the run with one line."""

import json

import pytest
from click.testing import CliRunner

import femcrowd
from femcrowd.cli import main
from femcrowd.cli.tool_commands import format_info
from femcrowd.driver import limits
from femcrowd.driver.estimate import case_info
from femcrowd.driver.limits import LIMITS, LimitError, Limits

from ..support import CASES

FIELD = {"velocity.type": "field", "velocity.uy": 0.0}
ROOM_TRIANGLES = 3648


@pytest.fixture(autouse=True)
def machine(monkeypatch):
    """A workstation of 16 GB, whatever runs the tests."""
    monkeypatch.setattr(limits, "physical_memory", lambda: 16e9)


@pytest.mark.parametrize("case, overrides, key", [
    ("room", {"output.every": 1e-9}, "output.every"),                       # 6e10 frames
    ("room", {"time.end": 1e300, "time.stop_when_empty": False}, "time.end"),
    ("room", {"time.dt": 1e-300}, "time.dt"),
    ("room", {"time.cfl": 1e-300}, "time.cfl"),
    ("room", {**FIELD, "velocity.ux": 1e20}, "velocity.ux"),                # steps from the CFL bound
    ("room", {**FIELD, "velocity.ux": 1, "velocity.uy": "1e20"}, "velocity.uy"),
    ("room", {"velocity.speed": 1e20}, "velocity.speed"),
    ("two-groups", {"populations.north.speed": 1e20}, "populations.north.speed"),
    ("room", {"mesh.refine": 8}, "mesh.refine"),                              # 239 million triangles
    ("room", {"time.end": 1e6, "time.dt": 0.02, "output.every": 100}, "time.end"),   # 5e7 rows of history
    ("narrow-door-micro", {"micro.count": 10 ** 9}, "micro.count"),
    ("narrow-door-micro", {"micro.radius": 1e-6}, "micro.radius"),
    ("narrow-door-micro", {"time.dt": 1e-300}, "time.dt"),
    ("narrow-door-micro", {"micro.fluctuation": 1e12}, "micro.fluctuation"),   # discs thrown 1e11 m a step
    ("narrow-door-micro", {"micro.fluctuation": 1e300}, "micro.fluctuation"),
    ("narrow-door-micro", {"micro.count": 5, "micro.radius": 1e-8}, "micro.radius"),   # 2.6e9 points on the walls
    ("room", {"velocity.speed": 101}, "velocity.speed"),                    # a speed in cm/s
    ("narrow-door-micro", {"velocity.speed": 101}, "velocity.speed"),
])
def test_a_runaway_run_is_refused_before_anything_is_written(tmp_path, case, overrides, key):
    case = femcrowd.load_case(CASES / case, overrides)
    with pytest.raises(LimitError) as refused:
        femcrowd.run(case, out=tmp_path / "out")
    assert refused.value.key == key and "limit" in refused.value.message
    assert "\n" not in str(refused.value)
    assert not (tmp_path / "out").exists()


def test_the_refined_mesh_is_counted_before_it_is_refined():
    case = femcrowd.load_case(CASES / "room", {"mesh.refine": 8})
    info = case_info(case)   # at once: the mesh is not refined
    assert info["plan"]["triangles"] == ROOM_TRIANGLES * 4 ** 8
    assert info["plan"]["memory"] > 16e9 * LIMITS.memory and "mesh.refine = 8" in info["over"]
    report = format_info(info)
    assert f"{ROOM_TRIANGLES * 4 ** 8} triangles after mesh.refine = 8" in report
    assert "beyond a limit: femcrowd run refuses it" in report


def test_info_prints_the_plan_the_run_checks():
    """The steps and frames of femcrowd info are those of the run's Plan; beyond a limit, info says so (exit 0)."""
    case = femcrowd.load_case(CASES / "room", {"time.end": 5})
    plan = femcrowd.Simulation(case).plan.values
    assert plan["steps"] == pytest.approx(5 / plan["dt"], abs=1) and plan["frames"] == 11
    assert case_info(case)["plan"] == plan
    result = CliRunner().invoke(main, ["info", str(CASES / "room"), "--set", "output.every=1e-9"])
    assert result.exit_code == 0 and "Traceback" not in result.output
    assert "6e+10 frames" in result.output and "beyond a limit" in result.output


def test_no_limits_runs_what_the_limits_refuse(tmp_path, monkeypatch):
    monkeypatch.setattr(limits, "LIMITS", Limits(frames=2))
    args = ["run", str(CASES / "room"), "-q", "--set", "time.end=1", "--out", str(tmp_path / "out")]
    refused = CliRunner().invoke(main, args)
    assert refused.exit_code == 2 and refused.stderr.count("\n") == 1
    assert "output.every = 0.5: 3 frames" in refused.stderr and "--no-limits" in refused.stderr
    assert not (tmp_path / "out").exists()
    done = CliRunner().invoke(main, [*args, "--no-limits"])
    assert done.exit_code == 0, done.output
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["final_time"] == 1


def test_the_help_of_no_limits_gives_the_limits():
    help_text = " ".join(CliRunner().invoke(main, ["run", "--help"]).output.split())
    frames, steps = (f"{n:.0e}".replace("e+0", "e") for n in (LIMITS.frames, LIMITS.steps))
    assert f"more than {frames} frames or {steps} steps" in help_text
    assert f"{LIMITS.memory:.0%} of this machine's memory" in help_text.replace(" %", "%")
    assert f"{LIMITS.disk / 1e9:.0f} GB of files" in help_text


def test_a_step_that_cannot_advance_t_stops_the_run(tmp_path):
    """U = 0.1 / (t - 0.5): dt shrinks with 0.5 - t until it is below one ulp of t; the run stops there with one
    line naming the velocity, after writing its summary and checkpoint as an interrupted run does."""
    out = tmp_path / "out"
    args = ["run", str(CASES / "room"), "-q", "--out", str(out), "--set", 'velocity.type="field"',
            "--set", 'velocity.ux="0.1/(t-0.5)"']
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    assert "velocity.ux = '0.1/(t-0.5)'" in result.stderr and "cannot advance beyond t = 0.49999" in result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"].startswith("stopped: ") and 0.4999999 < summary["final_time"] < 0.5
    assert (out / "checkpoint.npz").is_file()
    rows = (out / "history.csv").read_text().splitlines()
    assert len(rows) == summary["steps"] + 2   # the header, t = 0, one row per step: none after the stop


@pytest.mark.parametrize("radius, points", [(1e-8, 2.6e9), (1e-12, 2.6e10)])
def test_discs_of_a_few_nanometres_are_refused_before_their_walls_are_sampled(tmp_path, radius, points):
    """Three discs of micro.positions with radii of 1e-8 m (1e-12 m: 1e-9, the finest spacing): their contacts
    would sample the 26 m of walls at every radius, hundreds of GB; refused with the count of points, at once."""
    (tmp_path / "discs.csv").write_text("".join(f"{x},1,{radius}\n" for x in (1, 2, 3)).join(["x,y,r\n", ""]))
    case = femcrowd.load_case(CASES / "narrow-door-micro", {"micro.positions": str(tmp_path / "discs.csv")})
    with pytest.raises(LimitError) as refused:
        femcrowd.run(case, out=tmp_path / "out")
    assert refused.value.key == "micro.positions" and "3 discs of radius up to" in refused.value.message
    assert f"{points:.3g} points along the 26 m of walls" in refused.value.message
    assert refused.value.plan.values["wall_points"] == pytest.approx(points, rel=0.01)
    assert not (tmp_path / "out").exists()


def test_the_limit_of_speeds_is_the_stated_one():
    """A desired speed or a fluctuation of LIMITS.speed passes, just above is refused (docs/tools.md, "Limits")."""
    case = femcrowd.load_case(CASES / "narrow-door-micro", {"micro.fluctuation": LIMITS.speed, "time.end": 0.1})
    assert femcrowd.Simulation(case).plan.values["discs"] == 72   # set up: no LimitError
    for key in ("micro.fluctuation", "velocity.speed"):
        case = femcrowd.load_case(CASES / "narrow-door-micro", {key: LIMITS.speed * (1 + 1e-9), "time.end": 0.1})
        with pytest.raises(LimitError) as refused:
            femcrowd.Simulation(case)
        assert refused.value.key == key and f"more than the limit of {LIMITS.speed:g} m/s" in refused.value.message
