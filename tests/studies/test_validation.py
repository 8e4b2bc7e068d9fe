"""Door flows that converge and match experiments (femcrowd validate, docs/validation.md, docs/model.md "A speed
law whose door flow converges")."""

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.macro.stairs import STAIR_SPEEDS
from femcrowd.mesh.floorplan import build_mesh
from femcrowd.studies import validation

#: a small bottleneck: a 4 m x 3 m waiting area, a corridor 1 m long and 0.6 m wide, its end the exit
SMALL = """size = 0.3
[outer]
points = [[0, 0], [4, 0], [4, 1.2], [5, 1.2], [5, 1.8], [4, 1.8], [4, 3], [0, 3]]
[[exits]]
name = "exit"
from = [5, 1.2]
to = [5, 1.8]
"""


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """27 persons at 3 persons/m^2 in front of the small bottleneck, Weidmann's law."""
    case = tmp_path_factory.mktemp("small")
    (case / "plan.toml").write_text(SMALL)
    build_mesh(case / "plan.toml")
    (case / "case.toml").write_text('[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["exit"]\n[model]\nrho_max = 5.4\n'
                                    '[velocity]\nspeed = 1.34\nspeed_law = "weidmann"\n[initial]\n'
                                    'density = "3.0 * (x < 3)"\n[time]\nend = 60.0\n')
    return case


def specific_flow(case, *overrides):
    h = Simulation(load_case(case, list(overrides))).run().history
    return validation.flow(h["time"], h["evacuated"], h["mass"][0]) / 0.6, h["evacuated"][-1] / h["mass"][0]


def test_with_f_of_rho_max_zero_the_corners_jam_and_the_flow_falls_under_refinement(small):
    """Weidmann's law as it is (f(5.4) = 0): the crowd heading for the corridor's corners jams there for good,
    drained only by numerical diffusion; the flow falls as the mesh is refined and people are left."""
    coarse, _ = specific_flow(small, "mesh.refine=0")
    fine, out = specific_flow(small, "mesh.refine=2")
    assert fine < 0.75 * coarse and out < 0.95


def test_a_jam_that_pushes_drains_and_the_flow_converges(small):
    """push = 0.2: the projection moves the jam; everyone leaves and the flow agrees on two meshes to 2 %."""
    (coarse, out_coarse), (fine, out_fine) = (specific_flow(small, "velocity.push=0.2", f"mesh.refine={level}")
                                              for level in (0, 1))
    assert abs(fine - coarse) <= 0.02 * fine and min(out_coarse, out_fine) > 0.999


def test_validate_writes_the_table_the_runs_and_the_plot(tmp_path):
    out = tmp_path / "validation"
    result = CliRunner().invoke(main, ["validate", "--settings", "capacity,paper", "--widths", "1.0", "--levels", "1",
                                       "--serial", "--out", str(out)])
    assert result.exit_code == 0, result.output
    table = (out / "validation.md").read_text()
    assert "door capacity 1.9" in table and "| 1 | 1.90 |" in table
    assert "nan" not in table   # one mesh: no change between meshes to show, not "(nan %)"
    assert (out / "validation.png").stat().st_size > 10_000
    assert len((out / "validation.csv").read_text().splitlines()) == 3   # a header and two runs


def test_the_table_names_the_set_keys_with_each_setting(tmp_path):
    """--set changes every run after the setting's own keys, so validation.md names them with the setting: the
    discs run with Predtechenskii and Milinskii's law (docs/validation.md) no longer read as Weidmann's."""
    out = tmp_path / "validation"
    result = CliRunner().invoke(main, ["validate", "--settings", "capacity", "--widths", "1.0", "--levels", "1",
                                       "--serial", "--set", "time.end=2", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "| macro, constant speed, door capacity 1.9 /(m s); --set time.end=2 | 1 |" in (
        out / "validation.md").read_text()
    assert validation.label("discs") == validation.SETTINGS["discs"].label   # no --set: the label as it was


def test_every_experiment_has_a_source_and_says_how_it_was_read():
    rows = validation.experiments()
    assert len(rows) > 20 and all(r["source"] and r["where"] and r["note"] for r in rows)
    assert all(0.5 < r["specific_flow"] < 5 for r in rows if r["kind"] != "stair")   # persons/(m s)
    # the stair speeds (docs/floors.md, "Stair speeds"): each row says its direction; free speeds are those named
    stairs = validation.experiments("stair")
    assert len(stairs) == 26 and all(r["note"].split(";")[0] in ("up", "down") and 0.1 < r["speed"] < 2
                                     for r in stairs)
    named = {r["note"].split("femcrowd name ")[1]: r["speed"] for r in stairs if "femcrowd name" in r["note"]}
    assert len(named) == 6 and all(STAIR_SPEEDS[name] == pytest.approx(v, rel=1e-4) for name, v in named.items())


def test_an_unknown_setting_is_one_line(tmp_path):
    result = CliRunner().invoke(main, ["validate", "--settings", "pushy", "--out", str(tmp_path / "v")])
    assert result.exit_code == 2 and "unknown setting" in result.output


@pytest.mark.slow
def test_the_weidmann_push_flow_at_the_1_m_bottleneck_converges_near_the_experiments(tmp_path):
    """The variant weidmann-push (Weidmann's law, push 0.2, door capacity 1.9) at the 1 m bottleneck of femcrowd
    validate: the specific flow changes by less than 5 % between the last two of three meshes and lies within
    25 % of the experiments' 1.9 persons/(m s) (Seyfried et al. 2009: 1.90 at 1.0 m)."""
    tasks = validation.plan(["weidmann-push"], [1.0], 3, 1, tmp_path)
    flows = np.array([validation.run_task(task)["specific_flow"] for task in tasks])
    assert abs(flows[-1] - flows[-2]) <= 0.05 * flows[-1], flows
    assert abs(flows[-1] - 1.9) <= 0.25 * 1.9, flows


def test_a_wide_bottleneck_is_the_2_4_m_scene_magnified(tmp_path):
    """Up to 2.4 m the scene is the one of docs/validation.md (8 m x 6 m, a corridor 2 m long, the crowd on the
    first 6 m); beyond, every length times w / 2.4, so that the queue in front of a 5 m door lasts as long."""
    import tomllib

    def plan(width):
        directory = validation.scene(width, tmp_path)
        return (tomllib.loads((directory / "bottleneck.toml").read_text()),
                load_case(directory)["initial"]["density"])

    (narrow, crowd), (wide, wide_crowd) = plan(1.0), plan(4.8)
    assert narrow["size"] == 0.25 and narrow["exits"][0]["size"] == 0.1 and crowd == "2.5 * (x < 6)"
    assert narrow["outer"]["points"] == [[0, 0], [8, 0], [8, 2.5], [10, 2.5], [10, 3.5], [8, 3.5], [8, 6], [0, 6]]
    assert wide["size"] == 0.5 and wide["exits"][0]["size"] == 0.2 and wide_crowd == "2.5 * (x < 12)"
    assert wide["outer"]["points"] == [[0, 0], [16, 0], [16, 3.6], [20, 3.6], [20, 8.4], [16, 8.4], [16, 12], [0, 12]]


def test_the_diagram_of_predtechenskii_s_law_is_the_published_one(tmp_path):
    """femcrowd validate --diagram: in RiMEA test 4's corridor the uniform crowd walks at the law's speed, so speed
    and specific flow are Predtechenskii and Milinskii's (D = 0.3: 47 m/min, 14.1 m/min / 0.1 m^2 = 2.35
    persons/(m s) at 3 persons/m^2); a law without a published diagram is refused in one line."""
    from femcrowd.studies import diagram

    table, text, _ = diagram.diagram(tmp_path / "d", ("recommended",), densities=(3.0,), levels=1, serial=True)
    row = table[0]
    assert row["speed"] == pytest.approx(47 / 60, rel=1e-6) and row["published_speed"] == pytest.approx(47 / 60)
    assert row["specific_flow"] == pytest.approx(14.1 / 6, rel=1e-5) and row["within"]
    assert (tmp_path / "d" / "diagram.md").read_text() == text and "| 3 | 0.783 / 0.783 |" in text
    label = validation.SETTINGS["recommended"].label
    assert f"| {label}; --set velocity.walls=paper | 3 |" in diagram.markdown(table, ("velocity.walls=paper",))
    result = CliRunner().invoke(main, ["validate", "--diagram", "--settings", "capacity", "--out", str(tmp_path / "e")])
    assert result.exit_code == 2 and "no published diagram" in result.output


@pytest.mark.slow
def test_predtechenskii_s_law_with_auto_capacities_passes_the_capacity_of_the_width_on_two_meshes(small):
    """The setting "recommended" (Predtechenskii and Milinskii's law) at the small 0.6 m bottleneck: the law carries
    more than the door's capacity of its width (2.08 persons/(m s) at 0.6 m), so the door decides: everyone out,
    2.08 within 3 % on two meshes, which agree to 1 %."""
    overrides = validation.SETTINGS["recommended"].overrides
    (coarse, out_coarse), (fine, out_fine) = (specific_flow(small, *overrides, f"mesh.refine={level}")
                                              for level in (0, 1))
    assert min(out_coarse, out_fine) > 0.999
    assert fine == pytest.approx(2.08, rel=0.03) and abs(fine - coarse) <= 0.01 * fine


def test_the_setting_fast_is_the_recommended_one_with_the_fast_step_spelled_out(tmp_path):
    """validate --settings fast: the case of the setting "recommended" with FAST_STEP's three keys spelled out as
    --set (implicit-godunov at 1.5 times the median cell's CFL step), and nothing else different."""
    directory = validation.scene(1.0, tmp_path)
    settings = validation.SETTINGS
    fast = load_case(directory, settings["fast"].overrides).config
    spelled = ('scheme.transport="implicit-godunov"', "time.cfl_quantile=0.5", "time.cfl=1.5")
    assert fast == load_case(directory, [*settings["recommended"].overrides, *spelled]).config
    explicit = load_case(directory, settings["recommended"].overrides).config
    assert {s for s in fast if not isinstance(fast[s], dict) and fast[s] != explicit[s]} == set()
    differ = {(section, key) for section in fast if isinstance(fast[section], dict) for key in fast[section]
              if fast[section][key] != explicit[section].get(key)}
    assert differ == {("scheme", "transport"), ("time", "cfl_quantile"), ("time", "cfl")}
    assert (fast["scheme"]["transport"], fast["time"]["cfl_quantile"], fast["time"]["cfl"]) == (
        "implicit-godunov", 0.5, 1.5)


def test_the_fast_setting_keeps_the_invariants_and_passes_the_capacity_as_the_recommended_one(small):
    """The settings "fast" and "recommended" of femcrowd validate at the small 0.6 m bottleneck, plan's mesh: the door
    passes the capacity of its width, 2.08 persons/(m s), with either step; the fast step keeps mass + evacuated, 0 <=
    rho <= rho_max, p >= 0 and p (1 - rho) = 0 at every step, and its last person is out within 1 % of the explicit
    step's in under half its steps (measured +0.22 %, 233 steps against 652)."""
    runs = {name: Simulation(load_case(small, validation.SETTINGS[name].overrides)).run()
            for name in ("fast", "recommended")}
    for result in runs.values():
        h = result.history
        assert h["evacuated"][-1] > 0.999 * h["mass"][0]
        assert validation.flow(h["time"], h["evacuated"], h["mass"][0]) / 0.6 == pytest.approx(2.08, rel=1e-6)
    h, m0 = runs["fast"].history, runs["fast"].history["mass"][0]
    np.testing.assert_allclose(h["mass"] + h["evacuated"], m0, rtol=0, atol=1e-10 * m0)
    assert np.all(h["min_density"] >= 0) and np.all(h["max_density"] <= 5.4 * (1 + 1e-9))
    assert np.all(h["min_pressure"] >= 0) and np.all(h["complementarity"] <= 1e-9 * np.maximum(h["max_pressure"], 1))
    fast, explicit = (runs[name].summary for name in ("fast", "recommended"))
    assert fast["evacuation_time"] == pytest.approx(explicit["evacuation_time"], rel=0.01)
    assert 2 * fast["steps"] < explicit["steps"]
