"""Every shipped case runs through the real controller and shows the invariants of the
model (docs/model.md) at every step: mass balance, bounds, p >= 0, p = 0 off the saturated zone."""

import csv
import json

import numpy as np
import pytest
import pyvista

from femcrowd import load_case, run
from femcrowd.mesh.distance import Eikonal
from femcrowd.studies.settings import recommended

from ..support import CASES, assert_phases_within_wall


def run_macro(case, out):
    return run(case, out).summary

SHIPPED = sorted(p.name for p in CASES.iterdir() if (p / "case.toml").is_file())
MACRO = [name for name in SHIPPED if load_case(CASES / name)["model"]["type"] == "macro"]


def test_the_shipped_cases_are_there():
    assert {"room", "room-obstacles", "two-exits", "corridor-wall", "radial", "saturated-exit",
            "narrow-door"} <= set(MACRO)
    assert "narrow-door-micro" in SHIPPED  # micro: tests/driver/test_micro_runs.py


@pytest.mark.parametrize("name", [name for name in MACRO if "recommended settings" in load_case(CASES / name)["title"]])
def test_a_case_titled_with_the_recommended_settings_has_them(name):
    """The recommended settings (studies/settings.py, what `femcrowd new` writes) put on a shipped case whose title
    names them change none of its keys (cases/room-column and cases/bottleneck had Weidmann's law with a push)."""
    assert load_case(CASES / name, recommended(CASES / name)).config == load_case(CASES / name).config


@pytest.mark.parametrize("name", MACRO)
def test_shipped_case_invariants_at_every_step(name, tmp_path):
    case = load_case(CASES / name, ["output.every=1e9"])  # first and last frame only
    summary = run_macro(case, tmp_path)
    assert summary["status"] == "completed"
    with open(tmp_path / "history.csv") as f:
        rows = list(csv.DictReader(f))
    h = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    assert all(np.all(np.isfinite(v)) for v in h.values())
    rho_max = case["model"]["rho_max"]
    m0 = summary["initial_mass"]
    supplied = m0 + h.get("inflow", 0.0)          # cases with [[sources]]: what entered counts too
    assert np.max(supplied) > 0
    assert np.abs(h["mass"] + h["evacuated"] - supplied).max() <= 1e-10 * np.max(supplied)
    assert h["min_density"].min() >= 0
    assert h["max_density"].max() <= rho_max * (1 + 1e-9)
    assert h["min_pressure"].min() >= 0
    assert summary["max_pressure_unsaturated"] == 0.0      # p = 0 where rho < 1 - 1e-9
    assert summary["max_complementarity"] <= 1e-9 * max(summary["max_pressure_ever"], 1)
    for name, population in summary.get("populations", {}).items():   # each population, at every step
        m0 = population["initial_mass"]
        assert np.abs(h[f"mass_{name}"] + h[f"evacuated_{name}"] - m0).max() <= 1e-10 * m0, name
        assert population["min_density_ever"] >= 0 and population["max_mass_error"] <= 1e-10
    iterations = h["active_set_iterations"][h["active_set_iterations"] > 0]
    if iterations.size:
        assert iterations.mean() <= 3, iterations.mean()    # warm start
    if case["boundary"]["exits"] and name not in ("saturated-exit", "lwr-shock", "lwr-fan"):  # (exact solutions)
        assert summary["evacuation_time"] is not None       # evacuation scenes empty the room
    timing = dict(summary["timing"])
    assert_phases_within_wall(timing)


def test_room_output_reads_back_in_pyvista(tmp_path):
    """The README's default case: solution.pvd with the three cell arrays and the frame times."""
    case = load_case(CASES / "room", ["time.end=2", "output.every=0.5"])
    run_macro(case, tmp_path)
    reader = pyvista.get_reader(str(tmp_path / "solution.pvd"))
    assert np.allclose(reader.time_values, [0, 0.5, 1.0, 1.5, 2.0])
    reader.set_active_time_value(1.0)
    grid = reader.read()[0]
    assert {"density", "pressure", "velocity"} <= set(grid.cell_data.keys())
    assert grid.cell_data["velocity"].shape[1] == 3
    assert grid.n_cells == json.loads((tmp_path / "summary.json").read_text())["mesh"]["triangles"]
    density = np.asarray(grid.cell_data["density"])
    assert 0 <= density.min() and density.max() <= 1 + 1e-9


def test_only_the_fields_asked_for_are_written(tmp_path):
    case = load_case(CASES / "corridor-wall", ["output.fields=['density']", "time.end=0.1"])
    run_macro(case, tmp_path)
    grid = pyvista.get_reader(str(tmp_path / "solution.pvd")).read()[0]
    assert set(grid.cell_data.keys()) == {"density"}


def test_field_velocity_scene_computes_no_distance(monkeypatch, tmp_path):
    """'Leave out what a scene does not need': U given -> no distance field."""
    def forbidden(*args):
        raise AssertionError("distance computed for a field velocity")

    monkeypatch.setattr(Eikonal, "solve", forbidden)
    run_macro(load_case(CASES / "saturated-exit", ["time.end=0.05"]), tmp_path)


def test_no_projection_when_nothing_is_saturated(tmp_path):
    case = load_case(CASES / "corridor-wall", ["time.end=0.3"])  # the crowd reaches the wall at t = 0.5
    summary = run_macro(case, tmp_path)
    assert summary["active_set_iterations"]["steps_with_projection"] == 0
    assert summary["max_pressure_ever"] == 0
