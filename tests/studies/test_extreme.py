"""Stiff and extreme scenes (cases/stress) through the normal controller: every scene passes the
invariants of docs/model.md and its own exact checks (femcrowd.studies.stress)."""

import csv
import json

import pytest
from click.testing import CliRunner

from femcrowd.cli import main
from femcrowd.studies import stress

SCENES = stress.scenes()
LONG = "long-run"  # 10^4 steps: ~10-30 s here, run in full by the slow test and `femcrowd stress`


def explain(result):
    return "\n".join(f"{c.what}: {c.detail}" for c in result.failures())


def test_the_matrix_covers_the_issue():
    assert len(SCENES) >= 15 and set(stress.CHECKS) == set(SCENES)


@pytest.mark.parametrize("name", [n for n in SCENES if n != LONG])
def test_scene(tmp_path, name):
    result = stress.run_scene(name, tmp_path / name)
    assert result.passed, explain(result)
    assert len(result.checks) > len(stress.invariants(result.summary))  # the scene's own checks ran


def test_long_run_first_tenth(tmp_path):
    """The first 10^3 of the 10^4 steps, with every invariant (the full run is the slow test)."""
    result = stress.run_scene(LONG, tmp_path / LONG, overrides=("time.end=0.2",))
    assert result.summary["steps"] >= 1000
    assert all(c.ok for c in stress.invariants(result.summary)), explain(result)


@pytest.mark.slow
def test_long_run(tmp_path):
    result = stress.run_scene(LONG, tmp_path / LONG)
    assert result.passed, explain(result)


def test_checks_detect_violations(tmp_path):
    """The verdict can fail: a wrong exact solution, or a summary that breaks the invariants."""
    result = stress.run_scene("wall-a099", tmp_path / "a", overrides=("exact.a=0.98", "exact.x2=0.9"))
    assert not result.passed
    assert {c.what.split(" ")[0] for c in result.failures()} == {"front", "packed", "max"}
    broken = dict(result.summary, max_mass_error=1e-8, non_finite_values=3, min_pressure_ever=-1e-6,
                  max_density_ever=1 + 1e-8, status="interrupted")
    failed = {c.what for c in stress.invariants(broken) if not c.ok}
    assert failed == {"mass + evacuated conserved", "no NaN/inf", "p >= 0", "rho <= 1 + 1e-9", "completed"}


def test_cfl_above_one_is_refused():
    result = CliRunner().invoke(main, ["run", str(stress.CASES / "cfl-one"), "--set", "time.cfl=1.01"])
    assert result.exit_code == 2
    assert "time.cfl = 1.01: must be in (0, 1]" in result.stderr


def test_fixed_dt_is_capped_when_the_cfl_limit_shrinks(tmp_path):
    """U speeds up 21-fold: a dt valid at t = 0 would break positivity later, so steps are capped."""
    case = stress.CASES / "cfl-one"
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(tmp_path / "out"), "-q",
                                       "--set", 'velocity.ux="-(1 + 40 * t) * (1 + x)"', "--set", "time.dt=0.005",
                                       "--set", "time.end=0.5"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    with open(tmp_path / "out" / "history.csv", newline="") as f:
        dt = [float(row["dt"]) for row in csv.DictReader(f)][1:]  # row 0 is the initial state
    assert max(dt) == 0.005 and min(dt[:-1]) < 0.005 / 10
    assert summary["min_density_ever"] >= 0 and summary["max_mass_error"] < 1e-12


def test_implicit_transport_takes_a_fixed_dt_beyond_the_cfl_one_step(tmp_path):
    """The implicit transport accepts time.dt up to 100 x the CFL-1 step (checked at set-up): a dt of 20 x is
    taken as given, the same steps as time.cfl = 20."""
    def steps(name, *overrides):
        result = CliRunner().invoke(main, ["run", str(stress.CASES / "cfl-one"), "--out", str(tmp_path / name), "-q",
                                           "--set", 'scheme.transport="implicit"', "--set", "time.end=0.5",
                                           *overrides])
        assert result.exit_code == 0, result.output
        with open(tmp_path / name / "history.csv", newline="") as f:
            return [float(row["dt"]) for row in csv.DictReader(f)][1:]
    by_cfl = steps("cfl", "--set", "time.cfl=20")
    by_dt = steps("dt", "--set", f"time.dt={by_cfl[0]!r}")
    assert len(by_cfl) > 2 and by_dt == pytest.approx(by_cfl, rel=1e-12)


def test_stress_command(tmp_path):
    """`femcrowd stress`: a row per scene, the table files, exit code 1 when a scene fails."""
    out = tmp_path / "st"
    result = CliRunner().invoke(main, ["stress", "--only", "u-zero", "--only", "expanding-block", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "2/2 scenes pass" in result.output
    with open(out / "stress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["scene"] for r in rows] == ["u-zero", "expanding-block"] and {r["verdict"] for r in rows} == {"PASS"}
    assert (out / "stress.md").read_text().count("| PASS |") == 2

    cases = tmp_path / "cases" / "u-zero"
    cases.mkdir(parents=True)
    text = (stress.CASES / "u-zero" / "case.toml").read_text()
    mesh = (stress.CASES / "u-zero").resolve() / "../../../meshes/stress/room_exit.msh"
    text = text.replace('"../../../meshes/stress/room_exit.msh"', f'"{mesh.resolve()}"')
    (cases / "case.toml").write_text(text.replace('type = "field"', 'type = "field"\nux = 1'))
    result = CliRunner().invoke(main, ["stress", "--cases", str(cases.parent), "--out", str(tmp_path / "bad")])
    assert result.exit_code == 1
    assert "FAIL u-zero: density unchanged bit for bit" in result.output

    result = CliRunner().invoke(main, ["stress", "--only", "no-such-scene", "--out", str(tmp_path / "x")])
    assert result.exit_code == 2 and "no such scene" in result.stderr
    assert not (tmp_path / "x").exists()
