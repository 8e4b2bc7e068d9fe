"""Discs on a building's surface (docs/floors.md, "Discs on stairs"): each disc on one floor or stair, in that
piece's isometric chart; contacts on a piece and across a fold, never across floors; the stair's own speed."""

import meshio
import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import load_case
from femcrowd.cli import main
from femcrowd.driver.micro_model import MicroModel
from femcrowd.driver.reading import read_history, read_pvd
from femcrowd.driver.scene import build_scene
from femcrowd.mesh import load_domain
from femcrowd.micro import MicroSimulation
from femcrowd.micro.surface import Atlas, StairTooShort

from ..driver.test_resume import same_disc_run
from ..mesh.test_building import SLOPE, WALK, corridor
from ..support import CASES, MESHES

RADIUS = 0.2


def micro_case(tmp_path, *settings):
    """The corridor of tests/mesh/test_building.py (upper floor, stair, ground floor) with discs."""
    corridor(tmp_path, 0.25)
    (tmp_path / "case.toml").write_text(WALK)
    return load_case(tmp_path, ["model.type='micro'", f"micro.radius={RADIUS}", *settings])


def flat(xyz):
    """The corridor laid flat (an isometry of its surface): x of the upper floor, 4 + 5/4 (x - 4) on the stair,
    x + 1 on the ground floor; y as it is."""
    x = xyz[:, 0]
    return np.column_stack([np.where(x <= 4, x, np.where(x <= 8, 4 + SLOPE * (x - 4), x + 1)), xyz[:, 1]])


def walk(model, end):
    """Step the model to `end` or until no disc is left; yields after each step."""
    while model.sim.count and model.t < end - 1e-12:
        yield model.step(end)


def test_a_disc_walks_down_the_stair_at_the_stairs_speed(tmp_path):
    """One disc on the upper floor at x0 walks 4 - x0 at 1.3 m/s to the stair, 5 m down its slope at 0.65 m/s
    (velocity.speeds), 4 m on the ground floor to the exit at 1.3 m/s: it leaves at that time, to a step (it
    leaves at the step its centre crosses the exit, and the step that crosses a fold is walked at one speed)."""
    model = MicroModel(build_scene(micro_case(tmp_path, "micro.count=1", "initial.density='0.2 * (x <= 2)'")))
    x0, piece = model.surface.plan(model.sim.q)
    assert model.surface.names[piece[0]] == "upper"
    exact = (4 - x0[0, 0]) / 1.3 + 5.0 / 0.65 + 4.0 / 1.3
    speeds, stair = [], model.surface.names.index("stair")
    for info in walk(model, 30.0):
        if info.count and model.surface.piece(info.q)[0] == stair:
            speeds.append(np.hypot(*info.u[0]))
    assert model.sim.evacuated == 1 and abs(model.t - exact) <= 2 * model.tau, (model.t, exact, model.tau)
    assert len(speeds) > 50 and np.allclose(speeds[1:-1], 0.65, rtol=1e-6)   # along the slope, at its speed
    # at 1.3 m/s throughout it would be out 3.85 s sooner: the stair's speed is the stair's
    assert model.t > exact - 5.0 / 0.65 + 5.0 / 1.3 + 3.5


def test_a_crowd_down_the_stair_never_overlaps_on_it_nor_across_its_folds(tmp_path):
    """24 discs walk down the corridor, congested at the stair's head by its slower walk: at every step the gaps of
    every pair and of every disc to the corridor's walls, measured on the corridor laid flat (independently of the
    charts of the model), are >= -1e-10; the discs are counted once, on one floor or the stair."""
    model = MicroModel(build_scene(micro_case(tmp_path, "micro.count=24", "initial.density=0",
                                              "initial.regions={upper = 1.0}")))
    n0 = model.sim.count
    assert n0 == 24 and model.row()["on_upper"] == 24
    worst, across = np.inf, 0
    for info in walk(model, 40.0):
        q = flat(model.surface.xyz(info.q))
        if len(q) > 1:
            gap = np.linalg.norm(q[:, None] - q[None], axis=2) - 2 * RADIUS
            worst = min(worst, gap[np.triu_indices(len(q), 1)].min())
        if len(q):
            worst = min(worst, (q[:, 1] - RADIUS).min(), (2 - RADIUS - q[:, 1]).min())
        cl, lam = model.sim.contacts.cl, model.sim.contacts.lam
        across += np.any(lam[:len(cl.pi)][np.any(cl.shift != 0, axis=1)] > 0)   # a contact across a fold
        row = model.row(info)
        assert row["on_upper"] + row["on_stair"] + row["on_ground"] == info.count == n0 - info.evacuated
    assert worst >= -1e-10 and model.sim.evacuated == n0
    assert across > 10   # steps with discs in contact across a fold: those constraints were tested


def test_no_contact_across_floors():
    """Discs at the same plan point on the ground floor, the first floor and the stair above the ground floor
    (meshes/three_storeys.toml: stair_12 over x in [2, 6], y in [0, 1.5]) overlap in plan, but not on the surface:
    each walks at its desired velocity, with no contact."""
    domain = load_domain(MESHES / "three_storeys.msh", ["exit"])
    atlas = Atlas(domain)
    where = {"ground": (4.0, 0.75), "stair_12": (4.0, 0.75), "first": (8.0, 0.75), "second": (8.0, 0.75)}
    X = np.concatenate([atlas.chart(np.array([p]), atlas.names.index(name)) + atlas.offset[atlas.names.index(name)]
                        for name, p in where.items()])
    doors = [np.zeros(len(domain.length), bool) for _ in range(2)]
    doors[0][~domain.interior] = True
    sim = MicroSimulation(X, RADIUS, atlas.segments(doors[0], True), np.zeros((0, 2, 2)),
                          lambda q, t: np.tile([0.3, 0.0], (len(q), 1)), 0.05, surface=atlas)
    for _ in range(5):
        info = sim.step()
        assert info.contacts == 0 and np.allclose(info.u, [0.3, 0.0], rtol=0, atol=1e-14)
    assert sim.contacts.cl.m == 0 and len(atlas.cross_pairs(sim.q, 2.0)[0]) == 0
    with pytest.raises(StairTooShort, match="more than half the stair"):   # its pairs across the folds: not all found
        atlas.cross_pairs(sim.q, 3.0)
    z = atlas.xyz(sim.q)[:, 2]
    assert z[0] == 0 and 3 < z[1] < 6 and z[2] == 3 and z[3] == 6


def test_the_discs_frames_stand_at_their_elevations_and_move_along_the_slope(tmp_path):
    """discs_*.vtu and trajectories.txt: the discs at (x, y, z) on their floor or stair, the velocity of a disc on
    the stair tangent to it; history.csv counts the discs on each floor and on the stair (on_<group>)."""
    corridor(tmp_path, 0.25)
    (tmp_path / "case.toml").write_text(WALK)
    out = tmp_path / "out"   # the run ends as the first discs reach the ground floor (an empty frame is no VTU)
    settings = ["model.type='micro'", f"micro.radius={RADIUS}", "micro.count=6", "initial.density='0.2 * (x <= 2)'",
                "output.every=1", "time.end=12"]
    result = CliRunner().invoke(main, ["run", str(tmp_path), *[a for s in settings for a in ("--set", s)], "--out",
                                       str(out), "-q"])
    assert result.exit_code == 0, result.output
    on_stair = 0
    for _, name in read_pvd(out / "discs.pvd"):
        frame = meshio.read(out / name)
        x, z, u = frame.points[:, 0], frame.points[:, 2], frame.point_data["velocity"]
        floor = np.where(x <= 4, 3.0, np.where(x >= 8, 0.0, 3.0 - 0.75 * (x - 4)))
        assert np.allclose(z, floor, atol=1e-12)
        stair = (x > 4.3) & (x < 7.7)
        on_stair += stair.sum()
        assert np.allclose(u[stair, 2], -0.75 * u[stair, 0], atol=1e-12)
    assert on_stair > 0
    rows = np.loadtxt(out / "trajectories.txt", comments="#")   # PedPy's ID FR X Y Z: Z the elevation too
    x, z = rows[:, 2], rows[:, 4]
    assert np.allclose(z, np.where(x <= 4, 3.0, np.where(x >= 8, 0.0, 3.0 - 0.75 * (x - 4))), atol=1e-5)
    assert z.min() < 3.0
    history = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    assert np.array_equal(history["on_upper"] + history["on_stair"] + history["on_ground"], history["count"])
    assert history["on_stair"].max() > 0 and history["on_ground"].max() > 0


@pytest.mark.parametrize(("setting", "key"), [
    ("micro.positions='discs.csv'", "micro.positions"), ("velocity.route='congestion'", "velocity.route"),
])
def test_what_the_discs_cannot_do_on_a_building_is_refused_in_one_line(tmp_path, setting, key):
    corridor(tmp_path, 0.5)
    (tmp_path / "case.toml").write_text(WALK)
    (tmp_path / "discs.csv").write_text("x,y,r\n1,1,0.2\n")
    result = CliRunner().invoke(main, ["run", str(tmp_path), "--set", "model.type='micro'", "--set", setting,
                                       "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2 and f": {key} = " in result.output and "docs/floors.md" in result.output, \
        result.output
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()


def test_a_disc_run_on_a_building_resumes_bit_for_bit(tmp_path):
    """cases/corridor-stair in the disc model to 6 s (discs on the stair and across its folds, in contact), continued
    to 8 s with --resume: the uninterrupted run, bit for bit (the pairs across the folds are in the checkpoint)."""
    whole, part = tmp_path / "whole", tmp_path / "part"
    case, micro = CASES / "corridor-stair", ("--set", "model.type='micro'")
    for out, end, more in ((whole, 8, ()), (part, 6, ()), (part, 8, ("--resume",))):
        result = CliRunner().invoke(main, ["run", str(case), *micro, "--set", f"time.end={end}", "--out", str(out),
                                           "-q", *more])
        assert result.exit_code == 0, result.output
    assert read_history(part / "history.csv")["on_stair"][60:80].min() > 0
    same_disc_run(whole, part)


def test_the_pictures_draw_each_disc_with_its_floor():
    """plot/levels.py lays the floors side by side: a disc on a floor is shifted with it, a disc on a stair with the
    floor of the stair's head (as the stair is drawn), all at z = 0."""
    import pyvista as pv

    from femcrowd.plot.levels import Levels

    levels = Levels(load_domain(MESHES / "three_storeys.msh", ["exit"]))
    points = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 3.0], [1.0, 1.0, 6.0], [4.0, 5.0, 1.5], [4.0, 1.0, 4.5]])
    frame = pv.PolyData(points)
    frame.point_data["radius"] = np.full(5, RADIUS)
    drawn = levels.discs(frame)
    assert np.array_equal(drawn.points[:, 0], points[:, 0] + levels.step * np.array([0, 1, 2, 1, 2]))
    assert np.all(drawn.points[:, 2] == 0) and np.array_equal(drawn.point_data["radius"], frame.point_data["radius"])


def test_the_comparison_of_the_models_tells_the_floors_apart():
    """femcrowd compare's W2 between the crowds: a crowd on the ground floor and discs at the same plan points on
    the floor 3 m above are 3 m apart, not 0 (the distances are in space, z included)."""
    from femcrowd.studies.compare import _w2

    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    grid = meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]]))])
    discs = meshio.Mesh(points.mean(axis=0, keepdims=True) + [0.0, 0.0, 3.0], [])
    assert _w2(grid, np.array([0.5]), np.array([1.0]), discs) == pytest.approx(3.0, rel=1e-12)


def test_pieces_the_discs_cannot_walk_are_refused(tmp_path):
    """Two stairs sharing an edge (the corridor's stair cut in two groups) have no chart that unfolds both about a
    floor: refused, naming them (a run names mesh.file)."""
    domain = corridor(tmp_path, 0.5)
    stair = np.asarray(domain.mesh.subdomains["stair"])
    first = domain.centroid[stair, 0] < 6
    domain.mesh._subdomains = {**{k: v for k, v in domain.mesh.subdomains.items() if k != "stair"},
                               "stair_a": stair[first], "stair_b": stair[~first]}
    with pytest.raises(ValueError, match="'stair_a' and 'stair_b' share an edge but are not a floor and a stair"):
        Atlas(domain)
