"""femcrowd plot: offscreen pictures that are not blank, the animation, the curves, micro discs."""

import importlib.util

import imageio.v3 as iio
import matplotlib
import meshio
import numpy as np
import pytest
import pyvista as pv
from click.testing import CliRunner

from femcrowd import load_case, run
from femcrowd.cli import main
from femcrowd.driver.output import FrameSeries, HistoryFile, disc_frame, write_json
from femcrowd.driver.reading import RunDirectory
from femcrowd.mesh import file_checksum
from femcrowd.plot.axes import FRUIN_COLOURS
from femcrowd.plot.canvas import CMAPS, EXIT, FLOOR, WALL, Canvas, nice_top, tick_count
from femcrowd.plot.pictures import FloorPlan, curves_figure

from ..support import ROOT

WHITE = np.array([255, 255, 255])


def rgb(colour):
    return np.array([int(colour[k:k + 2], 16) for k in (1, 3, 5)])


def has_colour(image, colour, tol=12):
    """Is some pixel within tol (per channel) of the colour?"""
    return bool(np.any(np.all(np.abs(image.astype(int) - colour) <= tol, axis=-1)))


def colour_of(name, value):
    """RGB of a value in [0, 1] in a matplotlib colour map."""
    return np.round(255 * np.array(matplotlib.colormaps[name](value)[:3])).astype(int)


def check_not_blank(image, colours=20, filled=0.3):
    """Several distinct colours and a good part of the picture not background."""
    pixels = image.reshape(-1, 3).astype(np.int64)
    assert len(np.unique(pixels @ [65536, 256, 1])) >= colours
    assert np.mean(np.any(pixels != WHITE, axis=1)) >= filled


def test_canvas_renders_a_field_walls_and_exits_offscreen():
    """A 2 x 1 rectangle coloured by a density ramp: field, walls and exit all visible."""
    grid = pv.Plane(center=(1, 0.5, 0), i_size=2, j_size=1, i_resolution=20, j_resolution=10)
    grid.cell_data["density"] = grid.cell_centers().points[:, 0] / 2  # 0 .. 1 from left to right
    walls = np.array([[[0, 0], [2, 0]], [[2, 0], [2, 1]], [[2, 1], [0, 1]]], float)
    exits = np.array([[[0, 1], [0, 0]]], float)
    canvas = Canvas(((0, 2), (0, 1)), walls, exits, [], grid, width=300)
    canvas.show(grid, "density", (0.0, 1.0), CMAPS["density"], "density")
    canvas.title("test")
    image = canvas.image()
    canvas.close()
    assert image.shape[1] == 300
    check_not_blank(image)
    assert has_colour(image, colour_of(CMAPS["density"], 1.0), tol=20)  # the densest cells
    assert has_colour(image, rgb(EXIT)) and has_colour(image, rgb(WALL))
    # the left half of the floor is lighter than the right half (the ramp is drawn the right way round)
    rows = slice(canvas.height // 2 - 5, canvas.height // 2 + 5)
    left, right = image[rows, 40:140].sum(), image[rows, 160:260].sum()
    assert left > right


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """The shipped room run for 1 s (3 frames), written by `femcrowd run`."""
    out = tmp_path_factory.mktemp("room") / "out"
    result = CliRunner().invoke(main, ["run", str(ROOT / "cases" / "room"), "--out", str(out), "-q",
                                       "--set", "time.end=1", "--set", "output.every=0.5"])
    assert result.exit_code == 0, result.output
    assert f"femcrowd plot {out}" in result.output  # the run says how to look at its results
    return out


def test_plot_writes_pictures_animation_and_curves(short_run, tmp_path):
    result = CliRunner().invoke(main, ["plot", str(short_run), "-o", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in tmp_path.iterdir())
    density = [n for n in names if n.startswith("density_t")]
    pressure = [n for n in names if n.startswith("pressure_t")]
    assert density == ["density_t0000.0.png", "density_t0000.5.png", "density_t0001.0.png"]  # distinct frames
    assert len(pressure) == 3
    assert {"density.gif", "curves.png"} <= set(names)
    for name in density + pressure:
        check_not_blank(iio.imread(tmp_path / name)[..., :3])
    check_not_blank(iio.imread(tmp_path / "curves.png")[..., :3], filled=0.03)  # lines and text
    frames = iio.imread(tmp_path / "density.gif", index=None)
    assert len(frames) == 3  # every frame of the run (t = 0, 0.5, 1)
    assert not np.array_equal(frames[0], frames[-1])  # the crowd moved
    # the initial crowd (x < 4, 40 % of the floor at density 0.8) is drawn in the map's colour of 0.8
    colour = colour_of(CMAPS["density"], 0.8)
    first = iio.imread(tmp_path / "density_t0000.0.png")[..., :3]
    share = np.mean(np.all(np.abs(first.astype(int) - colour) <= 6, axis=-1))
    assert 0.2 < share < 0.4


def test_plot_times_snap_to_frames_and_bad_times_are_refused(short_run, tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["plot", str(short_run), "-o", str(tmp_path), "-q", "--no-animation",
                                  "--times", "0.74,1"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.glob("density_t*")) == ["density_t0000.5.png", "density_t0001.0.png"]
    assert not (tmp_path / "density.gif").exists()
    bad = runner.invoke(main, ["plot", str(short_run), "-o", str(tmp_path), "--times", "7"])
    assert bad.exit_code == 2
    assert bad.stderr.count("\n") == 1 and "--times" in bad.stderr and "[0, 1]" in bad.stderr


def test_plot_refuses_a_directory_without_frames(tmp_path):
    result = CliRunner().invoke(main, ["plot", str(tmp_path)])
    assert result.exit_code == 2
    assert result.stderr.startswith("femcrowd: error:") and result.stderr.count("\n") == 1


def write_discs(directory, frames=3, empty=0):
    """A hand-written micro output: discs.pvd (radius, velocity, pressure), history, summary; `empty`
    more frames with no disc left (the normal end of a micro run)."""
    mesh = ROOT / "meshes" / "room_one_door.msh"
    write_json(directory / "summary.json", {
        "case": {"title": "discs", "mesh": {"file": str(mesh), "refine": 0}, "boundary": {"exits": ["exit"]},
                 "model": {"type": "micro", "rho_max": 1.0}},
        "mesh": {"file": str(mesh), "sha256": file_checksum(mesh)}})
    series = FrameSeries(directory, "discs")
    history = HistoryFile(directory / "history.csv", ["time", "dt", "count", "evacuated", "contacts",
                                                       "max_overlap", "solver_iterations", "step_seconds"])
    x, y = np.meshgrid(np.arange(1, 4, 0.5), np.arange(0.5, 5.6, 0.5))
    centres = np.column_stack([x.ravel(), y.ravel()])
    for k in range(frames):
        q = centres + [2.0 * k, 0.0]
        pressure = q[:, 0] - q[:, 0].min()  # grows towards the door
        points = np.column_stack([q, np.zeros(len(q))])
        series.write(float(k), meshio.Mesh(points, [("vertex", np.arange(len(q))[:, None])], point_data={
            "radius": np.full(len(q), 0.24), "velocity": np.tile([1.0, 0, 0], (len(q), 1)), "pressure": pressure}))
        history.append({"time": float(k), "dt": 1.0, "count": len(q), "evacuated": 0, "contacts": 0,
                        "max_overlap": 0.0, "solver_iterations": 1, "step_seconds": 0.01})
    for k in range(frames, frames + empty):
        series.write(float(k), disc_frame(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0)))
        history.append({"time": float(k), "dt": 1.0, "count": 0, "evacuated": len(centres), "contacts": 0,
                        "max_overlap": 0.0, "solver_iterations": 0, "step_seconds": 0.01})
    history.close()
    return len(centres), float(pressure.max())


def test_plot_micro_discs_coloured_by_pressure(tmp_path):
    count, top = write_discs(tmp_path)
    result = CliRunner().invoke(main, ["plot", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.output
    plots = tmp_path / "plots"  # the default place of the pictures, apart from the run's files
    names = {p.name for p in plots.iterdir()}
    assert {"discs_t0000.png", "discs_t0001.png", "discs_t0002.png", "discs.gif", "curves.png"} <= names
    image = iio.imread(plots / "discs_t0002.png")[..., :3]
    check_not_blank(image)
    # the discs nearest the door carry the largest pressure: the colour of pressure / nice_top(top)
    assert has_colour(image, colour_of(CMAPS["pressure"], top / nice_top(top)), tol=6)
    assert len(iio.imread(plots / "discs.gif", index=None)) == 3


def test_plot_micro_run_whose_last_frames_have_no_disc(tmp_path):
    """Everyone left (the normal end of a micro run): the empty frames are drawn as an empty room."""
    write_discs(tmp_path, frames=2, empty=2)
    result = CliRunner().invoke(main, ["plot", str(tmp_path), "-q", "--times", "0,3"])
    assert result.exit_code == 0, result.output
    plots = tmp_path / "plots"
    assert {"discs_t0000.png", "discs_t0003.png", "discs.gif", "curves.png"} <= {p.name for p in plots.iterdir()}
    full, empty = (iio.imread(plots / f"discs_t000{k}.png")[..., :3] for k in (0, 3))
    check_not_blank(full)
    floor = lambda image: np.mean(np.all(np.abs(image.astype(int) - rgb(FLOOR)) <= 2, axis=-1))  # noqa: E731
    assert floor(empty) > floor(full) + 0.05  # the floor the discs covered is bare: no disc drawn
    assert len(iio.imread(plots / "discs.gif", index=None)) == 3  # until the first empty frame


@pytest.mark.parametrize("value, top, labels", [(0.636, 0.8, 5), (1.0, 1.0, 5), (1.01, 1.2, 5), (37, 40, 5),
                                                (0.0021, 0.0025, 6), (5.5, 6, 4), (0.0, 1.0, 5)])
def test_colour_bar_ranges_are_round(value, top, labels):
    assert nice_top(value) == pytest.approx(top)
    assert tick_count(nice_top(value)) == labels


def test_mp4_without_imageio_ffmpeg_is_one_line_and_writes_nothing(short_run, tmp_path):
    if importlib.util.find_spec("imageio_ffmpeg") is not None:
        pytest.skip("imageio-ffmpeg is installed: this checks the error a user sees without it")
    result = CliRunner().invoke(main, ["plot", str(short_run), "-o", str(tmp_path / "p"), "--mp4"])
    assert result.exit_code == 2 and "imageio-ffmpeg" in result.stderr and result.stderr.count("\n") == 1
    assert not (tmp_path / "p").exists()


def test_plot_of_a_run_with_measurements(tmp_path):
    """N-t and flow of the lines, density-speed of the areas, the level-of-service map of the maximum
    density, only for a run with measurements.csv; the map shows the levels of the densities met."""
    lines = [{"name": "door", "from": [10, 2.5], "to": [10, 3.5]}]
    areas = [{"name": "front", "polygon": [[8, 2], [10, 2], [10, 4], [8, 4]]}]
    case = load_case(ROOT / "cases" / "room", {"time.end": 6.0, "model.rho_max": 5.4, "initial.density": 4.0,
                                              "measure.lines": lines, "measure.areas": areas})
    out = run(case, tmp_path / "run").output_dir
    result = CliRunner().invoke(main, ["plot", str(out), "--no-animation", "-q"])
    assert result.exit_code == 0, result.output
    for name in ("lines.png", "areas.png", "level_of_service.png"):
        check_not_blank(iio.imread(out / "plots" / name)[..., :3], colours=10, filled=0.05)
    service = iio.imread(out / "plots" / "level_of_service.png")[..., :3]
    assert has_colour(service, rgb(FRUIN_COLOURS[-1])) and has_colour(service, rgb(FRUIN_COLOURS[0]))
    assert has_colour(service, rgb(WALL)) and has_colour(service, rgb(EXIT))   # the map shows the floor plan
    plain = run(load_case(ROOT / "cases" / "room", {"time.end": 1.0}), tmp_path / "plain").output_dir
    CliRunner().invoke(main, ["plot", str(plain), "--no-animation", "-q"])
    assert not (plain / "plots" / "lines.png").exists()


def test_a_closed_door_is_drawn_as_a_wall_at_the_frames_it_is_closed(tmp_path):
    """Issue 25: the room's exit opens at t = 0.5: green (an exit) only in the picture of t = 1, and the title of
    t = 0 says it is closed."""
    case = load_case(ROOT / "cases" / "room", {"time.end": 1.0, "output.every": 0.5,
                                              "boundary.open": {"exit": [[0.5, float("inf")]]}})
    out = run(case, tmp_path / "run").output_dir
    result = CliRunner().invoke(main, ["plot", str(out), "--no-animation", "-q", "--times", "0,1"])
    assert result.exit_code == 0, result.output
    closed, opened = (iio.imread(out / "plots" / f"density_t000{k}.0.png")[..., :3] for k in (0, 1))
    assert not has_colour(closed, rgb(EXIT), tol=30) and has_colour(opened, rgb(EXIT), tol=6)
    run_dir = RunDirectory(out)
    plan = FloorPlan(run_dir)
    assert plan.doors(0.0)[3] == ["exit"] and plan.doors(1.0)[3] == []


def test_curves_leave_out_the_panels_empty_for_the_whole_run_and_count_people(tmp_path):
    """Weidmann's law never saturates (f(rho_max) = 0): no pressure, no saturated area, so two panels; its
    densities are people per m^2 (even with rho_max = 1); the constant law with rho_max = 1 counts fractions of
    saturation, m^2 at rho_max, and keeps its pressure panels."""
    labels = {}
    for law, density in (("weidmann", 0.8), ("constant", 1.0)):   # (a saturated start: pressure at once)
        case = load_case(ROOT / "cases" / "room", {"time.end": 0.5, "velocity.speed_law": law,
                                                  "initial.density": density})
        fig = curves_figure(RunDirectory(run(case, tmp_path / law).output_dir))
        labels[law] = [(a.get_title(), a.get_ylabel()) for a in fig.axes]
    assert labels["weidmann"] == [("people inside and evacuated", "people"), ("exit flow rate", "flow rate (people/s)")]
    assert labels["constant"][:2] == [("people inside and evacuated", "crowd (m^2 at rho_max)"),
                                      ("exit flow rate", "flow rate (m^2 at rho_max/s)")]
    assert [title for title, _ in labels["constant"][2:]] == ["max pressure", "saturated area (rho = rho_max)"]


def test_the_disc_legend_lies_below_the_floor_plan():
    """Issue 25: the legend of the populations covered the entrance: it is in the band under the plan."""
    walls = np.array([[[0, 0], [4, 0]], [[4, 0], [4, 4]], [[4, 4], [0, 4]]], float)
    canvas = Canvas(((0, 4), (0, 4)), walls, np.array([[[0, 4], [0, 0]]], float), [], None, width=300)
    frame = pv.from_meshio(disc_frame(np.array([[1.0, 1.0], [2.0, 2.0]]), np.full(2, 0.2), np.zeros((2, 2)),
                                      np.zeros(2), {"population": np.array([0.0, 1.0])}))
    canvas.show_disc_populations(frame, ["a", "b"])
    (_, y), (_, tall) = canvas.legend.GetPosition(), canvas.legend.GetPosition2()
    canvas.close()
    assert (y + tall) * canvas.height <= canvas.BOTTOM + canvas.MARGIN   # below the plan's lowest pixel
