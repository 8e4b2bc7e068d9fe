"""Buildings (docs/floors.md): the plan of floors and stairs, its mesh, the geometry on the surface, a walk down a
stair against its exact time."""

import numpy as np
import pytest
import skfem
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.mesh import load_domain
from femcrowd.mesh.domain import Domain
from femcrowd.studies.recommended import FAST_STEP, FREE_SPEED

from ..support import MESHES

#: a straight corridor 2 m wide: the upper floor x in [0, 4] at z = 3, a stair down over x in [4, 8] in plan (rise 3,
#: run 4: 5 m along the slope), the ground floor x in [8, 12] at z = 0 with its exit at x = 12; unfolded, a
#: straight strip 13 m long
CORRIDOR = """
size = {size}
[[floors]]
name = "upper"
elevation = 3.0
outer.points = [[0, 0], [4, 0], [4, 2], [0, 2]]
[[floors]]
name = "ground"
elevation = 0.0
outer.points = [[8, 0], [12, 0], [12, 2], [8, 2]]
exits = [{{name = "exit", from = [12, 0], to = [12, 2]}}]
[[stairs]]
name = "stair"
lower = "ground"
upper = "upper"
foot = [[8, 2], [8, 0]]
head = [[4, 0], [4, 2]]
"""
SLOPE = 5.0 / 4.0   # length along the slope per metre of run


def corridor(tmp_path, size=0.25, refine=0):
    (tmp_path / "building.toml").write_text(CORRIDOR.format(size=size))
    result = CliRunner().invoke(main, ["mesh", str(tmp_path / "building.toml")])
    assert result.exit_code == 0, result.output
    return load_domain(tmp_path / "building.msh", ["exit"], refine=refine)


def unfolded(domain):
    """The building's mesh laid flat: the strip of the module's corridor, an isometry of its surface."""
    x = domain.points[:, 0]
    flat = np.where(x <= 4, x, np.where(x <= 8, 4 + SLOPE * (x - 4), x + 1))
    mesh = skfem.MeshTri(np.vstack([flat, domain.points[:, 1]]), domain.mesh.t, validate=False)
    mesh._boundaries = domain.mesh.boundaries
    return Domain(mesh, ["exit"])


def test_a_building_meshes_as_one_surface_with_a_group_per_floor_and_stair(tmp_path):
    domain = corridor(tmp_path)
    cells = domain.mesh.subdomains
    assert set(cells) == {"upper", "ground", "stair"} and domain.region.max() == 0   # one connected surface
    assert sum(len(c) for c in cells.values()) == domain.ncells
    z = domain.z[domain.triangles]
    assert np.all(z[cells["upper"]] == 3.0) and np.all(z[cells["ground"]] == 0.0)
    stair = domain.triangles[cells["stair"]]
    assert np.allclose(domain.z[stair], 3.0 * (8.0 - domain.points[stair, 0]) / 4.0, atol=1e-12)
    assert domain.area[cells["stair"]].sum() == pytest.approx(2 * 5.0, rel=1e-13)   # on the slope, not in plan
    assert domain.area.sum() == pytest.approx(2 * 13.0, rel=1e-13)
    assert domain.length[domain.groups["exit"]].sum() == pytest.approx(2.0, rel=1e-13)
    assert domain.length[domain.groups["wall"]].sum() == pytest.approx(2 * 13.0 + 2.0, rel=1e-13)


@pytest.mark.parametrize("refine", [0, 1])
def test_the_surface_geometry_is_that_of_the_building_laid_flat(tmp_path, refine):
    """Areas, facet lengths and the two-point transmissibilities (across the folds at the stair's ends too) equal
    those of the unfolded strip to round-off: the operators see the surface, as issue 37 asks."""
    domain = corridor(tmp_path, refine=refine)
    flat = unfolded(domain)
    assert np.allclose(domain.area, flat.area, rtol=1e-12, atol=0)
    assert np.allclose(domain.length, flat.length, rtol=1e-12, atol=0)
    assert np.allclose(domain.transmissibility, flat.transmissibility, rtol=1e-9, atol=1e-12)
    assert domain.clipped == flat.clipped and domain.non_delaunay == flat.non_delaunay
    mine, theirs = domain.statistics(), flat.statistics()
    for key in ("area", "min_angle_deg", "max_angle_deg", "h_max", "h_min"):
        assert mine[key] == pytest.approx(theirs[key], rel=1e-12), key
    # the flux of a plan velocity through a facet on the surface: the lift is 1 on the floors and across the
    # stair (run and slope edges alike), |e| J / |e|_surface on the stair's other facets
    assert domain.lift.min() == pytest.approx(1.0) and domain.lift.max() <= SLOPE * (1 + 1e-12)


def test_a_plane_floor_plan_keeps_its_plane_geometry(tmp_path):
    (tmp_path / "room.toml").write_text('[outer]\npoints = [[0, 0], [4, 0], [4, 3], [0, 3]]\n'
                                        '[[exits]]\nname = "exit"\nfrom = [4, 1]\nto = [4, 2]\n')
    assert CliRunner().invoke(main, ["mesh", str(tmp_path / "room.toml")]).exit_code == 0
    domain = load_domain(tmp_path / "room.msh", ["exit"])
    assert domain.z is None and domain.lift is None and domain.slope is None


def test_the_distance_to_the_exit_is_the_walk_over_the_stair(tmp_path):
    """d at every node is the exact walking distance over the surface (straight paths to a straight exit: the
    eikonal solver is exact there, docs/floors.md), 13 m from the far end of the upper floor."""
    case = tmp_path / "case.toml"
    corridor(tmp_path)
    case.write_text('[mesh]\nfile = "building.msh"\n[boundary]\nexits = ["exit"]\n[time]\nend = 1\n')
    velocity = Simulation(load_case(tmp_path)).model.solver.velocities[0]
    x = velocity.domain.points[:, 0]
    exact = np.where(x >= 8, 12 - x, np.where(x >= 4, 4 + SLOPE * (8 - x), 9 + (4 - x)))
    distance = next(iter(velocity.distance.values()))
    assert np.allclose(distance, exact, rtol=0, atol=1e-5)


@pytest.mark.parametrize(("name", "edit", "key", "message"), [
    ("foot off the floor", ("foot = [[8, 2], [8, 0]]", "foot = [[9, 2], [9, 0]]"), "stairs[0].foot",
     "the stair's end must lie on one straight edge"),
    ("upper floor below", ("elevation = 3.0", "elevation = -1.0"), "stairs[0].upper", "not above the lower floor"),
    ("unknown floor", ('lower = "ground"', 'lower = "groud"'), "stairs[0].lower", "expected the name of a floor"),
    ("unequal ends", ("head = [[4, 0], [4, 2]]", "head = [[4, 0], [4, 1]]"), "stairs[0]", "must be as wide"),
    ("stair named as a floor", ('name = "stair"', 'name = "upper"'), "stairs[0].name", "a name of its own"),
    ("unknown floor key", ("elevation = 0.0", "elevation = 0.0\nheight = 3"), "floors[1].height", "unknown key"),
])
def test_a_bad_building_is_one_line_naming_the_key(tmp_path, name, edit, key, message):
    (tmp_path / "building.toml").write_text(CORRIDOR.format(size=0.5).replace(*edit))
    result = CliRunner().invoke(main, ["mesh", str(tmp_path / "building.toml")])
    assert result.exit_code == 2 and f": {key} = " in result.output and message in result.output, result.output
    assert "Traceback" not in result.output and not (tmp_path / "building.msh").exists()


WALK = """
[mesh]
file = "building.msh"
[boundary]
exits = ["exit"]
[velocity]
speed = 1.3
speeds = { stair = 0.65 }
[initial]
density = "0.2 * (x >= 1) * (x <= 2)"
[time]
end = 30
[output]
every = 30
"""
#: the steps a building runs with: the case's (explicit upwind at cfl 0.5) and the fast step (implicit-godunov at 1.5
#: times the median cell's CFL step), the implicit transports being on the surface too
STEPS = pytest.mark.parametrize("step", [{}, FAST_STEP], ids=["upwind", "fast"])


def median_time(size, tmp_path, step=None):
    """The time half the crowd of WALK has left, and the run (with the overrides `step`)."""
    corridor(tmp_path, size)
    (tmp_path / "case.toml").write_text(WALK)
    run = Simulation(load_case(tmp_path, step or {})).run()
    h = run.history
    return float(np.interp(0.5 * h["mass"][0], h["evacuated"], h["time"])), run


@STEPS
def test_a_crowd_walks_down_the_stair_at_its_speed(tmp_path, step):
    """The person in the middle of a crowd on the upper floor (x = 1.5) walks 2.5 m to the stair at 1.3 m/s, 5 m
    down its slope at 0.65 m/s (velocity.speeds), 4 m to the exit at 1.3 m/s: half the crowd is out at that time
    (free flow: density 0.2, 0.4 on the stair), to the numerical diffusion of the upwind scheme (measured -0.05 %
    explicit, +0.16 % with the fast step); no mass is lost or made across the folds."""
    exact = 2.5 / 1.3 + 5.0 / 0.65 + 4.0 / 1.3
    median, run = median_time(0.25, tmp_path, step)
    h = run.history
    assert run.summary["status"] == "completed" and h["evacuated"][-1] == pytest.approx(h["mass"][0], rel=1e-3)
    assert np.abs(h["mass"] + h["evacuated"] - h["mass"][0]).max() <= 1e-14 * h["mass"][0]
    assert h["max_density"].max() < 1.0 and h["min_density"].min() >= 0.0   # never congested
    assert median == pytest.approx(exact, rel=2e-3)
    # the stair's own speed matters: at 1.3 m/s throughout the crowd would be out 3.85 s sooner
    assert exact - 5.0 / 0.65 + 5.0 / 1.3 < median - 3.5


def test_the_frames_stand_at_the_floors_elevations_and_the_history_counts_each_floor(tmp_path):
    """solution_*.vtu at (x, y, z): ParaView shows the building in 3D, the velocity lifted onto the stair's slope;
    history.csv: the people on each floor and on the stair (on_<group>), which add up to the crowd inside."""
    import pyvista

    corridor(tmp_path, 0.5)
    (tmp_path / "case.toml").write_text(WALK.replace("every = 30", "every = 5"))
    run = Simulation(load_case(tmp_path)).run(tmp_path / "out")
    h = run.history
    assert np.allclose(h["on_upper"] + h["on_stair"] + h["on_ground"], h["mass"], rtol=1e-12, atol=1e-15)
    assert h["on_upper"][0] == pytest.approx(h["mass"][0]) and h["on_stair"].max() > 0.5 * h["mass"][0]
    reader = pyvista.get_reader(str(tmp_path / "out" / "solution.pvd"))
    reader.set_active_time_value(10.0)
    grid = reader.read()[0]
    domain = run.domain
    assert np.allclose(grid.points[:, 2], domain.z) and grid.points[:, 2].max() == 3.0
    velocity = np.asarray(grid.cell_data["velocity"])
    stair = domain.mesh.subdomains["stair"]
    moving = stair[np.linalg.norm(velocity[stair], axis=1) > 0.1]
    # down the slope (a drop of 3 over a run of 4), tangent to it, at the stair's speed along it (free flow: u = U)
    assert len(moving) > 10 and np.allclose(velocity[moving, 2] / velocity[moving, 0], -3.0 / 4.0, rtol=1e-9)
    assert np.allclose(np.linalg.norm(velocity[moving], axis=1), 0.65, rtol=1e-9)


def test_the_three_storey_building_is_one_surface_over_floors_that_overlap_in_plan():
    """meshes/three_storeys.toml: three floors above each other (the same plan, less the stairs and stairwells),
    two stairs; floors overlapping in plan are told apart by their elevations, the surface is connected."""
    domain = load_domain(MESHES / "three_storeys.msh", ["exit"])
    areas = {name: domain.area[cells].sum() for name, cells in domain.mesh.subdomains.items()}
    expected = {"ground": 54.0, "first": 48.0, "second": 54.0, "stair_01": 7.5, "stair_12": 7.5}
    assert areas == pytest.approx(expected, rel=1e-12) and domain.region.max() == 0
    for name, z in (("ground", 0.0), ("first", 3.0), ("second", 6.0)):
        assert np.all(domain.z[domain.triangles[domain.mesh.subdomains[name]]] == z)
    assert domain.non_delaunay == 0 and domain.clipped == 0


@pytest.mark.parametrize(("setting", "key"), [
    ("scheme.transport=muscl", "scheme.transport"),
    ("measure.lines=[{name = 'l', from = [10, 0], to = [10, 2]}]", "measure.lines"),
])
def test_what_a_building_cannot_run_yet_is_refused_in_one_line(tmp_path, setting, key):
    corridor(tmp_path, 0.5)
    (tmp_path / "case.toml").write_text(WALK)
    result = CliRunner().invoke(main, ["run", str(tmp_path), "--set", setting, "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2 and f": {key} = " in result.output and "docs/floors.md" in result.output, \
        result.output
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()


@STEPS
def test_a_stair_head_takes_a_capacity_like_a_door(tmp_path, step):
    """The stair's ends are interior line groups (<stair>_head, <stair>_foot): boundary.capacity caps the flow onto
    the stair at c |head| (Colombo, Goatin 2007, as for a door), so the 4 people of the upper floor take at least
    4 / (0.2 x 2) = 10 s to pass it, and pass it all."""
    corridor(tmp_path, 0.5)
    crowd = WALK.replace('density = "0.2 * (x >= 1) * (x <= 2)"', "regions = { upper = 0.5 }")
    (tmp_path / "case.toml").write_text(crowd + "[boundary.capacity]\nstair_head = 0.2\n")
    h = Simulation(load_case(tmp_path, step)).run().history
    assert h["mass"][0] == pytest.approx(4.0, rel=1e-12)
    assert h["flow_stair_head"].max() <= 0.4 * (1 + 1e-12)
    assert np.sum(h["flow_stair_head"] * h["dt"]) == pytest.approx(4.0, rel=1e-9)   # every person passed once
    at_capacity = h["flow_stair_head"] >= 0.4 * (1 - 1e-9)
    assert np.sum(h["dt"][at_capacity]) > 8.0
    # the head meters the stair: at most the flow 0.4 / s walking at 0.65 m/s over 2 m, 0.31 persons/m^2 on its
    # 10 m^2 (all 4 people were on it at once without the capacity)
    assert 2.9 < h["on_stair"].max() <= 0.4 / (0.65 * 2) * 10 * (1 + 1e-3)
    assert np.abs(h["mass"] + h["evacuated"] - 4.0).max() <= 1e-13


@STEPS
def test_a_steady_stream_down_the_stair_is_as_dense_as_its_flow_and_speed_make_it(tmp_path, step):
    """People arrive at q = 0.5 /(m s) over the upper floor's west side (an entrance, 2 m): once steady, the
    density is q / v on each piece, 0.385 on the floors at 1.3 m/s and 0.769 on the stair at 0.65 m/s, so the
    stair holds 0.769 x 10 m^2 of its surface (a plan area would give 8 m^2), and they leave at 1 /s. Sources on a
    building: their mass balance to round-off. The fast step holds q / v on every piece, the upper floor too."""
    plan = CORRIDOR.format(size=0.5).replace("outer.points = [[0, 0], [4, 0], [4, 2], [0, 2]]", (
        'outer.points = [[0, 0], [4, 0], [4, 2], [0, 2]]\nexits = [{name = "entrance", from = [0, 2], to = [0, 0]}]'))
    (tmp_path / "building.toml").write_text(plan)
    assert CliRunner().invoke(main, ["mesh", str(tmp_path / "building.toml")]).exit_code == 0
    (tmp_path / "case.toml").write_text(WALK.replace('density = "0.2 * (x >= 1) * (x <= 2)"', "density = 0")
                                        + '[[sources]]\nboundary = "entrance"\nflow = 0.5\n')
    h = Simulation(load_case(tmp_path, step)).run().history
    assert np.abs(h["mass"] + h["evacuated"] - h["inflow"]).max() <= 1e-13 * h["inflow"][-1]
    steady = h["time"] >= 25.0
    assert np.allclose(h["on_stair"][steady], 0.5 / 0.65 * 10, rtol=1e-4)
    assert np.allclose(h["on_ground"][steady], 0.5 / 1.3 * 8, rtol=1e-4)
    # the upper floor: with the explicit step less in the cells along the entrance, whose arrivals start leaving
    # in the step they arrive; the fast step's enter its solve (macro/inflow.py)
    assert np.allclose(h["on_upper"][steady], 0.5 / 1.3 * 8, rtol=2e-2 if not step else 1e-4)
    assert h["max_density"][steady] == pytest.approx(0.5 / 0.65, rel=1e-4)
    late = h["time"] >= 20.0
    rate = np.polyfit(h["time"][late], h["evacuated"][late], 1)[0]
    assert rate == pytest.approx(1.0, rel=1e-4)


def test_femcrowd_new_names_the_stairs_of_a_building(tmp_path):
    """The case written for a building offers velocity.speeds for its stairs, commented: the figure is the user's."""
    result = CliRunner().invoke(main, ["new", str(tmp_path / "case"), "--mesh", str(MESHES / "three_storeys.msh")])
    assert result.exit_code == 0, result.output
    text = (tmp_path / "case" / "case.toml").read_text()
    assert "# speeds = { stair_01 = 0.6, stair_12 = 0.6 }" in text
    (tmp_path / "case" / "case.toml").write_text(text.replace("# speeds", "speeds"))
    speed = Simulation(load_case(tmp_path / "case")).model.solver.velocities[0].speed
    cells = load_domain(MESHES / "three_storeys.msh").mesh.subdomains
    assert np.all(speed[cells["stair_01"]] == 0.6) and np.all(speed[cells["first"]] == FREE_SPEED)
