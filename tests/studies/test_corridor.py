"""femcrowd's independent check: a corridor with a narrowing at its exit (femcrowd validate --scene corridor,
docs/validation.md "An independent check")."""

import math

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.mesh import load_domain
from femcrowd.studies import corridor, validation


def test_the_experiment_is_a_check_whose_mean_flow_is_its_persons_over_its_time():
    """The four runs of kind ``check``: 1.8 m corridor, exits 0.7 to 1.8 m, each with its source, and the flow
    the persons over the time of the last person out (to the CSV's rounding); never among the measured figures
    the bottleneck study is plotted against."""
    runs = corridor.runs()
    assert sorted(runs) == [0.7, 0.95, 1.2, 1.8]
    for width, r in runs.items():
        assert r["source"] and r["where"] and r["note"] and r["density_front"] is None
        assert r["flow"] == pytest.approx(r["persons"] / r["last_out_s"], abs=1e-3)
        assert r["specific_flow"] == pytest.approx(r["flow"] / width, abs=1e-3)
    assert not any(r["kind"] == "check" for r in validation.experiments("measured"))
    assert corridor.default_inflow() == runs[1.8]["flow"]


def test_the_scene_is_the_corridor_with_its_exit_and_entrance(tmp_path):
    """8 m x 1.8 m, the exit an opening of b_exit centred in the end wall, the entrance the whole first wall."""
    directory = corridor.scene(0.7, 148, 2.943, tmp_path)
    domain = load_domain(directory / "corridor.msh", ["exit"])
    length = {name: domain.length[f].sum() for name, f in domain.groups.items()}
    assert domain.area.sum() == pytest.approx(8.0 * 1.8, rel=1e-12)
    assert length["exit"] == pytest.approx(0.7, rel=1e-12) and length["entrance"] == pytest.approx(1.8, rel=1e-12)
    ends = domain.midpoint[domain.groups["exit"]]
    assert np.allclose(ends[:, 0], 8.0) and np.all(np.abs(ends[:, 1] - 0.9) < 0.35)
    assert np.allclose(domain.midpoint[domain.groups["entrance"], 0], 0.0)
    case = load_case(directory)
    assert case["sources"][0]["people"] == 148
    assert case["sources"][0]["end"] == pytest.approx(148 / 2.943, rel=1e-9)


@pytest.mark.parametrize("model", ["macro", "micro"])
def test_the_people_entered_are_the_integral_of_the_inflow(model, tmp_path):
    """20 persons at 10 persons/s: 20 have entered at 2 s and later (the inflow column), to round-off for the
    density model, exactly for the discs; at 1 s half of them (the integral of the constant rate)."""
    directory = corridor.scene(0.95, 20, 10.0, tmp_path)
    overrides = ["time.end=3", "output.every=0.5"] + (["model.type=micro", "micro.radius=0.2"] if model == "micro"
                                                      else [])
    h = Simulation(load_case(directory, overrides)).run().history
    entered = h["inflow"] + h["queued"]
    at = {t: entered[np.searchsorted(h["time"], t - 1e-12)] for t in (1.0, 3.0)}
    assert at[3.0] == pytest.approx(20, abs=1e-9) and h["inflow"][-1] == pytest.approx(20, abs=1e-9)
    assert at[1.0] == pytest.approx(10, abs=1e-9 if model == "macro" else 1)
    if model == "macro":   # mass + evacuated = what entered, to round-off
        assert np.allclose(h["mass"] + h["evacuated"], h["inflow"], atol=1e-9)


def test_the_measures_on_a_synthetic_count_of_people_out():
    """N(t) = 2 t out of 100 persons: the flow is the slope 2, the window 10 to 40 s (20 % to 80 % out), and a
    density rising as t has its time mean over that window, 25, exactly (trapezoidal rule on a line)."""
    t = np.linspace(0, 50, 501)
    out = 2 * t
    assert validation.flow(t, out, 100) == pytest.approx(2, rel=1e-12)
    inside = validation.queue(out, 100)
    assert t[inside][0] == pytest.approx(10) and t[inside][-1] == pytest.approx(40)
    assert corridor.front_density(t, t, out, 100) == pytest.approx(25, rel=1e-12)
    assert math.isnan(corridor.front_density(t[:2], t[:2], out[:2], 100))


def _row(setting, level, seed, flow, last_out, density, width=0.7):
    return {"setting": setting, "width": width, "level": level, "seed": seed, "flow": flow, "last_out": last_out,
            "front_density": density, "all_out": True}


def test_the_table_takes_the_finest_mesh_or_the_seeds_mean_and_divides_by_the_experiment():
    """Macro: the finest of three meshes, every mesh's value and the last change; discs: the seeds' mean; each
    divided by the experiment's figure (0.7 m: 1.732 persons/s, 85.44 s); no density was found: n/a."""
    rows = [_row("recommended", level, 0, f, t, 5.0) for level, f, t in ((0, 1.2, 110.0), (1, 1.3, 100.0),
                                                                         (2, 1.3, 98.0))]
    rows += [_row("discs", 0, seed, f, t, 4.0) for seed, f, t in ((1, 1.6, 90.0), (2, 1.8, 80.0))]
    table = corridor.summarise(rows)
    macro, discs = table
    assert macro["flow"] == 1.3 and macro["flow_ratio"] == pytest.approx(1.3 / 1.732)
    assert macro["last_out"] == 98.0 and macro["last_out_ratio"] == pytest.approx(98.0 / 85.44)
    assert macro["last_out_runs"] == "110.000 / 100.000 / 98.000 (2.0 %)"
    assert math.isnan(macro["front_density_ratio"]) and macro["front_density"] == 5.0
    assert discs["flow"] == pytest.approx(1.7) and discs["last_out"] == pytest.approx(85.0)
    assert discs["flow_runs"] == "1.60-1.80 over 2 seeds"
    text = corridor.markdown(table)
    assert "| 0.7 | 1.30 | 0.75 | 98.0 | 1.15 | 110.000 / 100.000 / 98.000 (2.0 %) | 5.00 | n/a | 3/3 |" in text
    assert "0.7 m: 148 persons, last out 85.44 s" in text
    named = corridor.markdown(table, ("micro.fluctuation=1",))   # the study's --set keys, named with each setting
    assert f"| {validation.SETTINGS['discs'].label}; --set micro.fluctuation=1 | 0.7 | 1.70 |" in named


@pytest.mark.parametrize("args, message", [
    (["--widths", "0.8"], "--widths: not an exit width of the experiment (widths: 0.7, 0.95, 1.2, 1.8 m)"),
    (["--inflow", "0"], "--inflow: expected persons per second in (0, 20]"),
    (["--inflow", "nan"], "--inflow: expected persons per second in (0, 20]"),
    (["--settings", "pushy"], "unknown setting"),
])
def test_bad_options_of_the_check_are_one_line_and_make_no_directory(args, message, tmp_path):
    out = tmp_path / "check"
    result = CliRunner().invoke(main, ["validate", "--scene", "corridor", *args, "--out", str(out)])
    assert result.exit_code == 2 and message in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1 and "Traceback" not in result.output
    assert not out.exists()


def test_inflow_is_an_option_of_the_corridor_only(tmp_path):
    result = CliRunner().invoke(main, ["validate", "--inflow", "2", "--out", str(tmp_path / "v")])
    assert result.exit_code == 2 and "--inflow: only for --scene corridor" in result.output
    assert not (tmp_path / "v").exists()


def test_the_check_writes_its_table_and_its_runs(tmp_path):
    """The quick variant of docs/validation.md at a high inflow (a short run): everyone out, the table with
    the ratios to the experiment and the runs' CSV."""
    out = tmp_path / "check"
    result = CliRunner().invoke(main, ["validate", "--scene", "corridor", "--settings", "paper", "--widths",
                                       "1.2", "--levels", "1", "--inflow", "6", "--serial", "--out", str(out)])
    assert result.exit_code == 0, result.output
    table = (out / "corridor.md").read_text()
    assert "| 1.2 |" in table and "| 1/1 |" in table and "170 persons" in table
    rows = (out / "corridor.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[0].startswith("setting,width,level,seed")


def test_the_papers_free_exit_passes_what_arrives(tmp_path):
    """The paper's model has no door capacity: through the 0.7 m exit it passes the inflow itself, 2.943
    persons/s while the queue would last, and everyone is out soon after the last arrival (50.3 s) and the
    8 m walk (6 s at 1.34 m/s)."""
    task = corridor.plan(["paper"], [0.7], 1, 1, tmp_path)[0]
    row = corridor.run_task(task)
    assert row["entered"] == pytest.approx(148, abs=1e-9) and row["all_out"]
    assert row["flow"] == pytest.approx(corridor.default_inflow(), rel=1e-5)
    assert 148 / 2.943 + 8 / 1.34 < row["last_out"] < 148 / 2.943 + 8 / 1.34 + 5


def test_a_run_that_ends_before_the_scene_is_empty_has_no_last_out(tmp_path):
    """Everyone but a speck is out, yet the run's own emptiness test (time.empty_fraction) is not passed by
    time.end: no evacuation time, so no last person out and not "all out" (it raised a TypeError)."""
    task = corridor.plan(["paper"], [0.7], 1, 1, tmp_path, overrides=("time.empty_fraction=1e-12", "time.end=62"))[0]
    row = corridor.run_task(task)
    assert row["evacuated"] >= 148 - 0.5
    assert not row["all_out"] and np.isnan(row["last_out"])


def test_the_corridor_full_behind_its_exit_at_capacity_keeps_every_invariant(tmp_path):
    """Issue 34: the recommended settings at time.cfl 1, steps cut to the 5 s output times. From about 40 s the
    corridor is saturated behind the 0.7 m exit at its capacity, a closed room of the projection, and a short
    step once left a cell with p > 0 below rho_max (complementarity 0.48) drained to -0.62 persons/m^2. Every
    step: mass + evacuated = inflow to 1e-10, 0 <= rho <= rho_max, p >= 0, p (1 - rho) = 0."""
    directory = corridor.scene(0.7, 148, 2.943, tmp_path)
    overrides = ["velocity.speed_law=predtechenskii", "velocity.walls=slip", "time.cfl=1.0",
                 f"velocity.speed={5 / 3!r}", 'boundary.capacity={exit="auto"}', "output.every=5", "time.end=60"]
    h = Simulation(load_case(directory, overrides)).run().history
    assert h["saturated_area"].max() > 0.95 * 8.0 * 1.8   # the corridor saturated
    assert np.abs(h["mass"] + h["evacuated"] - h["inflow"]).max() <= 1e-10 * 148
    assert h["min_density"].min() >= 0 and h["max_density"].max() <= 5.4 * (1 + 1e-9)
    assert h["min_pressure"].min() >= 0 and h["complementarity"].max() <= 1e-9
