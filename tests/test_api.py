"""femcrowd.api: a scene in memory runs as the same case from files does, bit for bit; its results keep the
model's invariants; bad geometry and settings are InputErrors naming the key; nothing is left on disk."""

import gc
import tomllib

import numpy as np
import pytest
from matplotlib.figure import Figure
from shapely import LineString, box

import femcrowd.api as fc
from femcrowd import Simulation, load_case
from femcrowd.errors import InputError
from femcrowd.mesh.floorplan import build_mesh

from .support import CASES, MESHES


def test_shapely_geometry_becomes_the_tables_of_a_plan():
    """The walkable box less an obstacle: its outline, the obstacle a hole, the exit and door segments."""
    plan = fc.plan_from_shapely(box(0, 0, 10, 6), {"exit": LineString([(10, 2), (10, 3)])},
                                doors={"door": LineString([(5, 0), (5, 6)])}, obstacles=[box(2, 2, 3, 3)], size=0.5)
    assert plan["size"] == 0.5
    assert sorted(map(tuple, plan["outer"]["points"])) == [(0, 0), (0, 6), (10, 0), (10, 6)]
    assert sorted(map(tuple, plan["holes"][0]["points"])) == [(2, 2), (2, 3), (3, 2), (3, 3)]
    assert plan["exits"] == [{"name": "exit", "from": [10.0, 2.0], "to": [10.0, 3.0]}]
    assert plan["doors"] == [{"name": "door", "from": [5.0, 0.0], "to": [5.0, 6.0]}]
    with pytest.raises(ValueError, match="MultiPolygon"):   # an obstacle across the room cuts it in two
        fc.plan_from_shapely(box(0, 0, 10, 6), {}, obstacles=[box(4, -1, 5, 7)])


@pytest.fixture(scope="module")
def narrow_door():
    """The plan of meshes/room_narrow_door.toml as a dict, the crowd of cases/narrow-door for 2 s."""
    plan = tomllib.loads((MESHES / "room_narrow_door.toml").read_text())
    return fc.Scene(plan, settings={"initial": {"density": "0.5 * (x < 4)"}, "time": {"end": 2.0}})


def test_a_scene_in_memory_runs_as_its_case_from_files(narrow_door, tmp_path):
    """The same plan meshed by femcrowd mesh and run by cases/narrow-door: the same history, bit for bit."""
    mesh = build_mesh(MESHES / "room_narrow_door.toml", tmp_path / "room.msh")
    files = Simulation(load_case(CASES / "narrow-door", {"mesh.file": str(mesh), "time.end": 2.0})).run().history
    memory = narrow_door.run().result.history
    assert set(files) == set(memory)
    for column in set(files) - {"step_seconds"}:
        assert np.array_equal(files[column], memory[column]), column


def test_the_results_keep_the_invariants(narrow_door):
    """Mass + evacuated = the initial mass in every row; the kept densities in [0, rho_max], their integral the
    history's mass at their times; the states kept at 0, every output.every and the end."""
    run = narrow_door.run()
    h = run.history
    assert np.allclose(h["mass"] + h["evacuated"], h["mass"].iloc[0], rtol=1e-12, atol=0)
    assert run.times == pytest.approx(np.arange(0.0, 2.01, 0.5))
    area = run.cells["area"].to_numpy()
    for t in run.times:
        rho = run.density(t)
        assert rho.min() >= 0 and rho.max() <= 1 + 1e-12
        row = int(np.argmin(np.abs(h["time"].to_numpy() - t)))
        assert h["time"].iloc[row] == pytest.approx(t) and rho @ area == pytest.approx(h["mass"].iloc[row], rel=1e-12)
    doors = run.doors
    assert doors.loc["exit", "through"] == pytest.approx(h["evacuated"].iloc[-1], rel=1e-12)
    for fig in (run.plot_map(1.0), run.plot_map(1.0, level_of_service=True), run.plot_nt()):
        assert isinstance(fig, Figure) and fig.axes


def test_the_disc_model_on_a_scene(narrow_door):
    """model.type = micro: discs counted, the kept discs as arrays, their count the history's at that time."""
    run = narrow_door.run(model={"type": "micro"}, micro={"radius": 0.2, "seed": 1}, time={"end": 1.0})
    h = run.history
    assert np.all(h["count"] + h["evacuated"] == h["count"].iloc[0])
    centres, radii = run.discs(1.0)
    assert centres.shape == (h["count"].iloc[-1], 2) and np.all(radii == 0.2)


@pytest.mark.parametrize("settings, key", [({"time": {"end": -1.0}}, "time.end"),
                                           ({"initial": {"peopel": 3}}, "initial.peopel")])
def test_bad_settings_name_their_key(narrow_door, settings, key):
    with pytest.raises(InputError, match=key.replace(".", r"\.")):
        narrow_door.case(**settings)


def test_bad_geometry_names_its_key_and_the_mesh_goes_with_the_scene():
    with pytest.raises(InputError, match=r"exits\[0\]"):
        fc.Scene(box(0, 0, 10, 6), exits={"exit": LineString([(5, 2), (5, 3)])})   # not on the boundary
    scene = fc.Scene(box(0, 0, 4, 3), exits={"exit": LineString([(4, 1), (4, 2)])}, size=0.5)
    mesh = scene.mesh
    assert mesh.is_file()
    del scene
    gc.collect()
    assert not mesh.exists() and not mesh.parent.exists()


def test_the_scene_before_any_run(narrow_door):
    """Scene.plot: the set-up alone (no step taken), the plan with its exit named with its width."""
    fig = narrow_door.plot()
    assert isinstance(fig, Figure) and "exit: 0.8 m" in {t.get_text() for t in fig.axes[0].texts}
    assert fig.axes[0].get_title() == "the scene: initial crowd at t = 0 s"
