"""Evacuation times under refinement (femcrowd evacuation-times): the times read off the evacuated curve, the
observed orders, and convergence to the exact times of the saturated evacuation (exact solution 3)."""

import csv
import math

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation
from femcrowd.case import load_case
from femcrowd.cli import main
from femcrowd.studies.evacuation import evacuation_times, observed, shares, study
from femcrowd.studies.recommended import FAST, FREE_SPEED
from femcrowd.studies.settings import recommended, with_settings

from ..support import CASES


def test_times_are_read_between_the_steps():
    t = np.linspace(0.1, 10.0, 100)
    assert evacuation_times(t, t, 10.0, (0.5, 0.9, 0.99, 1 - 1e-4)) == pytest.approx([5.0, 9.0, 9.9, 9.999])
    assert math.isnan(evacuation_times(t, 0.5 * t, 10.0, (0.6,))[0])   # never reached


def test_the_last_person_is_out_when_half_a_person_is_left():
    """The last person's share: all but 0.5 of 50 persons is 99 %; a crowd of less than a person has none."""
    case = {"time": {"empty_fraction": 1e-4}}
    t = np.linspace(0.1, 10.0, 100)
    assert shares(case, 50.0)[-1] == pytest.approx(0.99)
    assert evacuation_times(t, 5 * t, 50.0, shares(case, 50.0)) == pytest.approx([5.0, 9.0, 9.9, 9.999, 9.9])
    assert math.isnan(evacuation_times(t, 0.03 * t, 0.3, shares(case, 0.3))[-1])


def test_orders_and_the_richardson_estimate_of_a_first_order_series():
    """t_k = T + C h_k: order 1 between every three levels, and Richardson's estimate is T exactly."""
    h = [0.4, 0.2, 0.1, 0.05]
    diffs, orders, limits = observed([30.0 + 7.0 * x for x in h], h)
    assert diffs[1:] == pytest.approx([-1.4, -0.7, -0.35])
    assert orders[2:] == pytest.approx([1.0, 1.0]) and limits[-1] == pytest.approx(30.0)
    assert math.isnan(orders[1]) and math.isnan(limits[1])


def test_no_richardson_estimate_where_the_differences_change_sign():
    """Oscillatory convergence (d = +1, -0.5, +0.2): the orders are read, the estimate is not (cases/two-exits,
    all but 1e-4 out: -0.041 s, then +0.040 s, order 0.04, would extrapolate 1.4 s past the finest level)."""
    h = [0.4, 0.2, 0.1, 0.05]
    diffs, orders, limits = observed([10.0, 11.0, 10.5, 10.7], h)
    assert diffs[1:] == pytest.approx([1.0, -0.5, 0.2])
    assert orders[2:] == pytest.approx([1.0, math.log2(2.5)])
    assert all(math.isnan(t) for t in limits)


def saturated_times(k, s0, shares):
    """Exact solution 3: the block empties as s(t) = (s0 + 2/k) exp(-k t / 2) - 2/k; the share q is out when
    s = (1 - q) s0."""
    return [2 / k * math.log((s0 + 2 / k) / ((1 - q) * s0 + 2 / k)) for q in shares]


def test_the_saturated_evacuation_times_converge_to_the_exact_ones(tmp_path):
    """Upwind DG0 on three meshes: the errors of the times of 50, 90 and 99 % out halve with h (first order,
    docs/model.md), that of the last 1e-4 (the smeared tail drains last) falls too."""
    rows, text, out = study(CASES / "saturated-exit", 3, tmp_path / "times", overrides=["time.end=2.0"],
                            serial=True)
    exact = saturated_times(1.0, 1.0, (0.5, 0.9, 0.99, 1 - 1e-4))
    names = [c for c in rows[0] if c.startswith("t ")]
    errors = np.array([[abs(r[n] - e) for n, e in zip(names, exact)] for r in rows])
    assert np.all(errors[1:] < errors[:-1])                      # closer to the exact times on each level
    assert np.all(errors[1:, :3] < 0.6 * errors[:-1, :3])       # first order
    assert np.all(errors[-1, :3] < 0.06 * np.array(exact[:3]))
    assert (out / "evacuation.csv").is_file() and "Richardson" in (out / "evacuation.md").read_text()
    # the flow while 20 to 80 % are out lies between the exact rates -ds/dt = s/2 + 1 at 80 % and 20 % out
    assert all(1.1 * 0.99 < r["flow"] < 1.4 * 1.01 for r in rows), [r["flow"] for r in rows]


def test_a_micro_case_is_refused_in_one_line(tmp_path):
    result = CliRunner().invoke(main, ["evacuation-times", str(CASES / "narrow-door-micro"),
                                       "--out", str(tmp_path / "t")])
    assert result.exit_code == 2 and "model.type" in result.output and result.output.count("\n") == 1
    assert not (tmp_path / "t").exists()


def test_a_transport_a_building_cannot_run_is_refused_in_one_line_before_any_run(tmp_path):
    """muscl on cases/corridor-stair (a building: muscl reconstructs in plan): one line naming the case file,
    scheme.transport and its value, exit code 2 and no directory, as femcrowd run does; before, every level ran
    and failed (exit code 1, a table of nan)."""
    result = CliRunner().invoke(main, ["evacuation-times", str(CASES / "corridor-stair"), "--levels", "2", "--serial",
                                       "--out", str(tmp_path / "t"), "--set", 'scheme.transport="muscl"'])
    assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
    assert "corridor-stair/case.toml: scheme.transport = 'muscl'" in result.output and "building" in result.output
    assert not (tmp_path / "t").exists()


def test_a_failed_level_leaves_the_others_tabulated(tmp_path, monkeypatch):
    """Level 1 of 3 raises: levels 0 and 2 keep their times, level 1 has none and its one-line reason; exit 1."""
    from femcrowd.macro.projection.lcp import ProjectionError
    from femcrowd.studies import evacuation

    run_level = evacuation.run_level

    def failing_at_level_1(task):
        if task.level == 1:
            raise ProjectionError("no convergence\nin 50 iterations")
        return run_level(task)
    monkeypatch.setattr(evacuation, "run_level", failing_at_level_1)
    result = CliRunner().invoke(main, ["evacuation-times", str(CASES / "saturated-exit"), "--levels", "3",
                                       "--serial", "--set", "time.end=1.0", "--out", str(tmp_path), "-q"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert result.stderr.count("\n") == 1 and "1 of 3 runs failed" in result.stderr
    report = (tmp_path / "evacuation.md").read_text()
    assert "failed: default, level 1 (channel_exit.msh refine 1): ProjectionError: no convergence in 50" in report
    rows = report.split("## default")[1].splitlines()
    level = {r.split("|")[1].strip(): r for r in rows if r.startswith("| ") and r.split("|")[1].strip().isdigit()}
    assert set(level) == {"0", "1", "2"} and "| 0.37 |" in level["2"] and "| - |" in level["1"]


def test_the_recommended_settings_give_every_exit_and_interior_door_the_capacity_of_its_width():
    """--settings recommended on a building (corridor-stair: its exit and the two ends of its stair, interior
    lines): the law at its free speed, no push, slip walls, cfl 1 and "auto" on the three doors; a --set wins."""
    overrides = with_settings(CASES / "corridor-stair", "recommended", ["velocity.walls=paper"])
    case = load_case(CASES / "corridor-stair", overrides)
    velocity = case["velocity"]
    assert (velocity["speed_law"], velocity["speed"], velocity["push"]) == ("predtechenskii", FREE_SPEED, 0.0)
    assert case["time"]["cfl"] == 1.0 and velocity["walls"] == "paper"
    assert case["boundary"]["capacity"] == {"exit": "auto", "stair_foot": "auto", "stair_head": "auto"}
    assert with_settings(CASES / "corridor-stair", "case", ["velocity.walls=paper"]) == ("velocity.walls=paper",)


def saturated_exit_times(out, options) -> np.ndarray:
    """The times of evacuation.csv of `evacuation-times` on cases/saturated-exit, two levels to t = 3 s, with
    the command's `options`, written to `out` (one row per level)."""
    result = CliRunner().invoke(main, ["evacuation-times", str(CASES / "saturated-exit"), "--levels", "2",
                                       "--serial", "-q", "--set", "time.end=3.0", *options, "--out", str(out)])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(open(out / "evacuation.csv")))
    return np.array([[float(r[k]) for k in r if k.startswith("t ")] for r in rows])


def test_settings_recommended_runs_what_the_explicit_overrides_run(tmp_path):
    """The option gives the times of the --set overrides docs/convergence.md spelled out before it, to the bit;
    the law slows the saturated crowd of exact solution 3 (f = 0.8 at rho_max = 1 person/m^2): the 50, 90 and 99 %
    times are 15 to 25 % later."""
    explicit = ["velocity.speed_law=predtechenskii", "velocity.speed=1.6666666666666667", "velocity.push=0",
                "velocity.walls=slip", "time.cfl=1", 'boundary.capacity={exit="auto"}']
    runs = {"option": ["--settings", "recommended"], "explicit": [a for o in explicit for a in ("--set", o)],
            "case": []}
    times = {name: saturated_exit_times(tmp_path / name, options) for name, options in runs.items()}
    assert np.isfinite(times["case"]).all() and np.array_equal(times["option"], times["explicit"])
    assert np.all(times["option"][:, :3] > 1.1 * times["case"][:, :3])   # 50, 90, 99 % out
    assert "velocity.speed_law" in (tmp_path / "option" / "evacuation.md").read_text()


def test_the_fast_settings_are_the_recommended_ones_with_the_fast_step():
    """--settings fast on corridor-stair: exactly the overrides of FAST (the law, slip walls, implicit-godunov at
    1.5 times the median cell's step), the law's free speed, no push and "auto" on the three doors; the recommended
    ones differ only in the step; a --set wins."""
    fast = with_settings(CASES / "corridor-stair", "fast", ["time.cfl=1.2"])
    assert fast[:-1] == recommended(CASES / "corridor-stair", ["time.cfl=1.2"], FAST) and fast[-1] == "time.cfl=1.2"
    keys = [text.split("=", 1)[0] for text in fast[:-1]]
    assert keys == [*FAST, "velocity.speed", "velocity.push", "boundary.capacity"]
    case = load_case(CASES / "corridor-stair", with_settings(CASES / "corridor-stair", "fast"))
    velocity, time = case["velocity"], case["time"]
    assert (velocity["speed_law"], velocity["speed"], velocity["push"], velocity["walls"]) == (
        "predtechenskii", FREE_SPEED, 0.0, "slip")
    assert (case["scheme"]["transport"], time["cfl_quantile"], time["cfl"]) == ("implicit-godunov", 0.5, 1.5)
    assert case["boundary"]["capacity"] == {"exit": "auto", "stair_foot": "auto", "stair_head": "auto"}
    assert load_case(CASES / "corridor-stair", fast)["time"]["cfl"] == 1.2
    explicit = dict(t.split("=", 1) for t in with_settings(CASES / "corridor-stair", "recommended"))
    differ = {k for k, v in dict(t.split("=", 1) for t in fast[:-1]).items() if explicit.get(k) != v}
    assert differ == {"scheme.transport", "time.cfl_quantile", "time.cfl"}


def test_settings_fast_runs_what_the_explicit_overrides_run(tmp_path):
    """evacuation-times --settings fast gives the times of its overrides spelled out with --set, to the bit."""
    explicit = ["velocity.speed_law=predtechenskii", "velocity.walls=slip", 'scheme.transport="implicit-godunov"',
                "time.cfl_quantile=0.5", "time.cfl=1.5", "velocity.speed=1.6666666666666667", "velocity.push=0",
                'boundary.capacity={exit="auto"}']
    times = {name: saturated_exit_times(tmp_path / name, options)
             for name, options in {"option": ["--settings", "fast"],
                                   "explicit": [a for o in explicit for a in ("--set", o)]}.items()}
    assert np.isfinite(times["option"]).all() and np.array_equal(times["option"], times["explicit"])
    assert "implicit-godunov" in (tmp_path / "option" / "evacuation.md").read_text()


def test_the_fast_step_keeps_the_invariants_and_empties_with_the_recommended_step():
    """cases/wide-door (50 people through a 2.4 m door at its capacity; deterministic) with the fast settings:
    mass + evacuated = the initial mass, 0 <= rho <= 1, p >= 0 and p (1 - rho) = 0 at every step; everybody out
    within 1 % of the recommended explicit step's evacuation time on the same mesh (measured +0.21 %) in under
    a third of its steps (162 against 846)."""
    runs = {}
    for name in ("recommended", "fast"):
        case = load_case(CASES / "wide-door", with_settings(CASES / "wide-door", name))
        runs[name] = Simulation(case).run()
    fast, explicit = runs["fast"], runs["recommended"]
    h, m0, rho_max = fast.history, fast.summary["initial_mass"], case["model"]["rho_max"]   # persons/m^2
    np.testing.assert_allclose(h["mass"] + h["evacuated"], m0, rtol=0, atol=1e-10 * m0)
    assert np.all(h["min_density"] >= 0) and np.all(h["max_density"] <= rho_max * (1 + 1e-9))
    assert np.all(h["min_pressure"] >= 0) and np.all(h["complementarity"] <= 1e-9 * np.maximum(h["max_pressure"], 1))
    assert fast.summary["remaining_fraction"] < 1e-4
    assert fast.summary["evacuation_time"] == pytest.approx(explicit.summary["evacuation_time"], rel=0.01)
    assert 3 * fast.summary["steps"] < explicit.summary["steps"]



def lwr_fan_study(out, *options):
    """`evacuation-times` on cases/lwr-fan with the recommended settings to t = 6 s (everyone out in about 5 s)
    with `options`, written to `out`: (the command's result, the rows of evacuation.csv)."""
    result = CliRunner().invoke(main, ["evacuation-times", str(CASES / "lwr-fan"), "--serial", "-q", "--settings",
                                       "recommended", "--set", "time.end=6", *options, "--out", str(out)])
    rows = list(csv.DictReader(open(out / "evacuation.csv"))) if (out / "evacuation.csv").is_file() else []
    return result, rows


def test_a_finer_level_joined_with_an_earlier_study_tabulates_as_one_series(tmp_path):
    """Levels 0-1, then 1-2 joined with them: the levels, steps and times of one three-level run to the bit (level
    1, run twice, checked), and its table of differences, orders and Richardson's estimates."""
    one, first, both = (lwr_fan_study(tmp_path / name, *options) for name, options in (
        ("one", ["--levels", "3"]), ("first", ["--levels", "2"]),
        ("both", ["--levels", "2", "--set", "mesh.refine=1", "--join", str(tmp_path / "first")])))
    assert [r.exit_code for r, _ in (one, first, both)] == [0, 0, 0], both[0].output

    def measured(rows):
        return [{k: v for k, v in r.items() if k not in ("wall_seconds", "cpu_seconds")} for r in rows]

    def orders(name):
        return (tmp_path / name / "evacuation.md").read_text().split("| share out |")[1]
    assert len(one[1]) == 3 and measured(both[1]) == measured(one[1])
    assert orders("both") == orders("one") and "(0.8" in orders("one")    # the 50 % time's order
    assert "first/evacuation.csv` (--join)" in (tmp_path / "both" / "evacuation.md").read_text()


def test_a_join_with_other_settings_is_refused_and_the_new_levels_kept(tmp_path):
    """Level 1 run in both, first at another CFL number: one line naming the earlier file, the level and its mesh,
    exit 2, and this run's two levels written alone; a missing study or this study's own --out: refused before
    any run, the earlier study left as it was."""
    lwr_fan_study(tmp_path / "first", "--levels", "2", "--set", "time.cfl=0.5")
    result, rows = lwr_fan_study(tmp_path / "both", "--levels", "2", "--set", "mesh.refine=1",
                                 "--join", str(tmp_path / "first"))
    assert result.exit_code == 2 and result.stderr.count("\n") == 1 and "Traceback" not in result.output
    assert f"{tmp_path / 'first' / 'evacuation.csv'}: level 1 = 'channel_exit_right.msh refine 1'" in result.stderr
    assert "not joined" in result.stderr
    assert [r["mesh"] for r in rows] == ["channel_exit_right.msh refine 1", "channel_exit_right.msh refine 2"]
    for join, out, says in (("none", "new", "not found"), ("first", "first", "own --out")):
        result, _ = lwr_fan_study(tmp_path / out, "--levels", "2", "--join", str(tmp_path / join))
        assert result.exit_code == 2 and result.output.count("\n") == 1 and says in result.output, result.output
    assert not (tmp_path / "new").exists()
    assert len(list(csv.DictReader(open(tmp_path / "first" / "evacuation.csv")))) == 2
