"""``femcrowd new`` (issue 34 item 5): the recommended settings of docs/validation.md by default, with the door
capacity keyed by the names of the mesh's exits and interior doors; the paper's model with ``--model paper``,
exactly the file ``femcrowd new`` wrote before (tests/case/new_paper/)."""

import math
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.mesh.capacity import width_capacity
from femcrowd.studies.recommended import DOOR_CAPACITY, FREE_SPEED, MACRO

from ..support import MESHES

GOLDEN = Path(__file__).parent / "new_paper"


def new(case_dir, mesh, *options):
    result = CliRunner().invoke(main, ["new", str(case_dir), "--mesh", str(mesh), *options])
    assert result.exit_code == 0, result.output
    return load_case(case_dir)


@pytest.mark.parametrize("mesh, doors", [(MESHES / "two_exits.msh", ["exit_narrow", "exit_wide"]),
                                         (MESHES / "stress" / "two_rooms.msh", ["exit", "door"])])
def test_a_new_case_has_the_recommended_settings_and_runs(tmp_path, mesh, doors):
    """The capacities ("auto": that of each door's width) are keyed by the mesh's own door names (exits and an
    interior door), Predtechenskii and Milinskii's law at its free speed (100 m/min) with no push; the case runs a
    few steps with every door capped (its flow column) and keeps mass, 0 <= rho <= rho_max and p >= 0."""
    case = new(tmp_path / "case", mesh)
    assert case["boundary"]["capacity"] == {name: DOOR_CAPACITY for name in doors} and DOOR_CAPACITY == "auto"
    assert case["model"]["rho_max"] == 5.4 and case["velocity"]["speed"] == FREE_SPEED == 100 / 60
    assert case["velocity"]["speed_law"] == "predtechenskii" and case["velocity"]["push"] == 0
    assert all(case[key.split(".")[0]][key.split(".")[1]] == value for key, value in MACRO.items())   # the step too
    result = Simulation(load_case(tmp_path / "case", {"time.end": 0.3})).run(stop_when_empty=False)
    h = result.history
    assert len(h["time"]) > 3 and result.summary["status"] == "completed"
    assert sorted(result.summary["doors"]) == sorted(doors)
    assert all(f"flow_{name}" in h for name in doors)
    assert h["mass_error"].max() < 1e-12 and h["min_density"].min() >= 0
    assert h["max_density"].max() <= 5.4 * (1 + 1e-9) and h["min_pressure"].min() >= 0
    assert h["mass"][0] == pytest.approx(2.0 * Simulation(case).scene.domain.area.sum(), rel=1e-12)


def test_a_new_case_runs_long_enough_for_its_exits_capacities(tmp_path):
    """time.end: the walk (0.4 x the floor's diagonal, in 10 s) and the crowd (2 persons/m^2 on the floor) through
    the exits at the capacities of their widths, rounded up to 10 s: the 20 m x 12 m floor of two_exits.msh, 480 persons
    through 1 m and 2 m at 2.08 and 2.365 persons/(m s)."""
    case = new(tmp_path / "case", MESHES / "two_exits.msh")
    assert width_capacity(2.0) == pytest.approx(2.08 + (2.57 - 2.08) * 0.8 / 1.2)
    walk, people = 100.0, 2.0 * Simulation(case).scene.domain.area.sum()
    expected = 10.0 * math.ceil((walk + people / (width_capacity(1.0) * 1.0 + width_capacity(2.0) * 2.0)) / 10.0)
    assert case["time"]["end"] == expected == 170.0


@pytest.mark.parametrize("mesh", ["entrance_hall", "two_exits", "square"])
def test_the_paper_switch_writes_the_file_new_wrote_before(tmp_path, mesh):
    """The golden files are what `femcrowd new` wrote before the recommended settings (paths replaced)."""
    case_dir, mesh_file = tmp_path / mesh, MESHES / f"{mesh}.msh"
    case = new(case_dir, mesh_file, "--model", "paper")
    assert case["model"]["rho_max"] == 1.0 and case["boundary"]["capacity"] == {}
    relative = Path(os.path.relpath(mesh_file, case_dir.resolve())).as_posix()
    text = (case_dir / "case.toml").read_text().replace(relative, "{mesh}").replace(str(case_dir), "{case}")
    assert text == (GOLDEN / f"{mesh}.toml").read_text()


def test_new_refuses_an_unknown_model(tmp_path):
    result = CliRunner().invoke(main, ["new", str(tmp_path / "c"), "--mesh", str(MESHES / "square.msh"),
                                       "--model", "papers"])
    assert result.exit_code == 2 and "'papers' is not one of 'recommended', 'paper'" in result.output
    assert not (tmp_path / "c").exists()
