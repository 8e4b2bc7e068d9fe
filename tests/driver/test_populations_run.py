"""Runs with several populations and speed laws through the driver: the outputs of the contract
(density_<name> arrays, mass_<name> / evacuated_<name> columns), and a case without the new keys
unchanged bit for bit when it names its one population or its constant law."""

import numpy as np
import pytest
import pyvista

from femcrowd import Simulation, load_case, run
from femcrowd.driver.reading import read_history

from ..support import CASES


def test_one_named_population_or_the_constant_law_change_nothing():
    """[populations.crowd] with the [initial] density, or speed_law = "constant": the same run, bit for bit."""
    base = {"time.end": 2.0}
    plain = Simulation(load_case(CASES / "room", base)).run()
    named = Simulation(load_case(CASES / "room", {**base, "initial.density": 0.0,
                                                  "populations.crowd.density": "0.8 * (x < 4)"})).run()
    constant = Simulation(load_case(CASES / "room", {**base, "velocity.speed_law": "constant"})).run()
    for other in (named, constant):
        assert np.array_equal(other.state.rho, plain.state.rho) and np.array_equal(other.state.p, plain.state.p)
        assert set(other.history) == set(plain.history)           # no per-population columns
        assert all(np.array_equal(other.history[k], plain.history[k]) for k in plain.history if k != "step_seconds")


def test_two_groups_outputs(tmp_path):
    """Frames carry density_<name> next to density (their sum), history.csv mass_<name>, evacuated_<name>;
    each group leaves by its own door."""
    case = load_case(CASES / "two-groups", {"output.every": 5.0})
    summary = run(case, tmp_path).summary
    h = read_history(tmp_path / "history.csv")
    assert {"mass_north", "evacuated_north", "mass_south", "evacuated_south"} <= set(h)
    assert np.allclose(h["mass_north"] + h["mass_south"], h["mass"], rtol=1e-12)
    reader = pyvista.get_reader(str(tmp_path / "solution.pvd"))
    reader.set_active_time_value(reader.time_values[1])
    grid = reader.read()[0]
    total = grid.cell_data["density_north"] + grid.cell_data["density_south"]
    assert np.allclose(total, grid.cell_data["density"], atol=1e-12)
    # the north group heads for the narrow door: it leaves there; the south group by the wide door
    by_exit = summary["evacuated_by_exit"]
    assert summary["populations"]["north"]["evacuated"] > 0.99 * summary["populations"]["north"]["initial_mass"]
    assert by_exit["exit_narrow"] > 0.9 * summary["populations"]["north"]["initial_mass"]
    assert by_exit["exit_wide"] > 0.9 * summary["populations"]["south"]["initial_mass"]


def test_counterflow_populations_cross():
    """Each population reaches its own exit through the other one: the model lets them through."""
    summary = Simulation(load_case(CASES / "counterflow")).run().summary
    for name, entry in summary["populations"].items():
        assert entry["evacuated"] > 0.99 * entry["initial_mass"], name
    by_exit = summary["evacuated_by_exit"]
    assert by_exit["east"] > 0.99 * summary["populations"]["eastbound"]["initial_mass"]
    assert by_exit["west"] > 0.99 * summary["populations"]["westbound"]["initial_mass"]
    assert summary["max_pressure_ever"] > 0                      # they jam where they meet


def test_bottleneck_weidmann_needs_no_projection():
    """cases/bottleneck with Weidmann's law as it is (no push, no door capacity): f(5.4) = 0, never projected."""
    case = load_case(CASES / "bottleneck", {"time.end": 20.0, "velocity.push": 0.0, "boundary.capacity": {}})
    summary = Simulation(case).run().summary
    assert not summary["projection_needed"] and summary["active_set_iterations"]["max"] == 0
    assert summary["max_density_ever"] < case["model"]["rho_max"]
    assert summary["evacuated"] > 0



def test_arrivals_count_in_the_mass_balance_of_their_population(tmp_path):
    """A source feeding the second of two populations: each population's mass + evacuated = initial + its
    arrivals (mass_error_<name> at round-off), and only the fed one receives them."""
    text = (CASES / "entrance" / "case.toml").read_text().replace("../../meshes", str(CASES.parent / "meshes"))
    text = text.replace('boundary = "entrance"', 'boundary = "entrance"\npopulation = "arriving"')
    (tmp_path / "case.toml").write_text(text)
    case = load_case(tmp_path, {"time.end": 12.0, "populations.inside.density": "2.0 * (x > 6)",
                                "populations.arriving.density": 0.0})
    sim = Simulation(case)
    sim.run()
    row = sim.model.row()
    assert sim.model.sources.arrived[0] == 0.0 and sim.model.sources.arrived[1] > 4.0
    assert row["mass_error_inside"] < 1e-13 and row["mass_error_arriving"] < 1e-13
    assert row["mass_arriving"] + row["evacuated_arriving"] == pytest.approx(row["inflow"], rel=1e-12)
