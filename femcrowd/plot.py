"""Pictures, animation and curves of a run directory (``femcrowd plot OUTDIR``).

Reads what a run wrote (case-format contract): ``solution.pvd`` (macro: cell
data density, pressure) and/or ``discs.pvd`` (micro: points with radius,
pressure), ``history.csv`` and ``summary.json``; writes, next to them or in
``out``:

- ``density_tXXX.png`` and ``pressure_tXXX.png`` at the chosen times (macro),
  ``discs_tXXX.png`` (micro: discs coloured by their pressure);
- ``density.gif`` (or ``.mp4`` with imageio-ffmpeg; micro: ``discs.gif``);
- ``curves.png``: people inside and evacuated, flow rate per exit, max
  pressure, saturated area (micro: contacts and max overlap) against time.

Pictures are rendered offscreen by pyvista (EGL, no display needed). The floor
plan comes from the run's mesh (file and exits recorded in summary.json):
walls in grey, exits in green, obstacles (holes) filled in light grey. When
the mesh cannot be found the boundary of the frames is drawn, all as walls.
"""

import csv
import importlib.util
import json
import logging
import os
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")  # before vtk creates a window
import pyvista as pv  # noqa: E402

from .errors import InputError  # noqa: E402
from .mesh import file_checksum, load_domain  # noqa: E402

pv.OFF_SCREEN = True
log = logging.getLogger("femcrowd.plot")

BACKGROUND, TEXT = "white", "#202020"
WALL, EXIT, OBSTACLE, FLOOR = "#6e6e6e", "#00a651", "#bdbdbd", "#ebebe6"
CMAPS = {"density": "YlOrRd", "pressure": "PuBu"}
PICTURE_WIDTH, ANIMATION_WIDTH = 1000, 640
DEFAULT_PICTURES = 4        # default times: evenly spaced until the crowd is down to ...
PICTURE_REMAINING = 0.05    # ... this fraction of the initial one
ANIMATION_REMAINING = 0.01  # the animation stops at the first frame below this fraction
ANIMATION_FRAMES = 80       # at most this many frames (evenly subsampled)
ANIMATION_SECONDS = 10.0    # target length of the animation
CURVES_REMAINING = 1e-3     # curves are shown until this fraction of the crowd is left


class RunOutput:
    """What a run directory holds: summary, history columns, frame series (time, file)."""

    def __init__(self, directory):
        self.directory = d = Path(directory)
        if not d.is_dir():
            raise InputError(d, None, None, "not a directory (give the output directory of a run)")
        self.summary = json.loads((d / "summary.json").read_text()) if (d / "summary.json").is_file() else {}
        self.history = read_history(d / "history.csv") if (d / "history.csv").is_file() else {}
        self.frames = {stem: read_pvd(d / f"{stem}.pvd") for stem in ("solution", "discs")
                       if (d / f"{stem}.pvd").is_file()}
        self.frames = {stem: series for stem, series in self.frames.items() if series}
        if not self.frames:
            raise InputError(d, None, None, "no frames (solution.pvd or discs.pvd): not the output "
                             "directory of a run (femcrowd run CASE writes one)")
        case = self.summary.get("case") or _case_copy(d / "case.toml")  # no summary yet: run in progress
        self.title = case.get("title") or d.name
        self.rho_max = case.get("model", {}).get("rho_max", 1.0)

    def read(self, stem, k):
        return pv.read(self.directory / self.frames[stem][k][1])

    def inside(self):
        """(time, people inside) from history.csv, or None."""
        h = self.history
        column = "mass" if "mass" in h else "count" if "count" in h else None
        return (h["time"], h[column]) if column and len(h["time"]) else None

    def time_remaining(self, fraction):
        """First history time at which at most ``fraction`` of the initial crowd is inside, or None."""
        inside = self.inside()
        if inside is None or inside[1][0] <= 0:
            return None
        below = np.flatnonzero(inside[1] <= fraction * inside[1][0])
        return float(inside[0][below[0]]) if len(below) else None


def _case_copy(path):
    """The run's copy of case.toml as written (no defaults filled), or {}."""
    try:
        return tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return {}


def read_history(path):
    """history.csv as a dict of float arrays (one per column)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    complete = [r for r in rows[1:] if len(r) == len(rows[0])]  # a run in progress may be mid-row
    values = np.array(complete, float).reshape(-1, len(rows[0]))
    return {name: values[:, k] for k, name in enumerate(rows[0])}


def read_pvd(path):
    """The (time, file) list of a PVD collection."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise InputError(path, None, None, f"cannot read the PVD collection: {err}") from None
    return [(float(e.get("timestep", 0.0)), e.get("file")) for e in root.iter("DataSet")]


def floor_plan(run):
    """walls, exits (segment arrays (n, 2, 2)), exit labels [(name, midpoint, outward normal)] and the
    floor (triangles, PolyData) from the run's mesh, or None when it cannot be found."""
    mesh, case = run.summary.get("mesh", {}), run.summary.get("case", {})
    file = Path(mesh.get("file", ""))
    if not mesh.get("file") or not file.is_file():
        log.warning("mesh of the run %s: all boundary edges drawn as walls",
                    f"not found ({file})" if mesh.get("file") else "unknown (no summary.json)")
        return None
    if mesh.get("sha256") and file_checksum(file) != mesh["sha256"]:
        log.warning("mesh %s changed since the run: walls and exits drawn from its current version", file)
    domain = load_domain(file, case.get("boundary", {}).get("exits", []),
                         case.get("mesh", {}).get("refine", 0))
    labels = [(name, domain.midpoint[f].mean(axis=0), domain.normal[f].mean(axis=0))
              for name, f in domain.exit_group.items()]
    floor = pv.PolyData.from_regular_faces(np.column_stack([domain.points, np.zeros(len(domain.points))]),
                                           domain.triangles)
    return domain.boundary_segments("wall"), domain.boundary_segments("exit"), labels, floor


def _lines(segments, z):
    """Segments (n, 2, 2) as a PolyData of lines at height z."""
    n = len(segments)
    points = np.column_stack([segments.reshape(-1, 2), np.full(2 * n, z)])
    return pv.PolyData(points, lines=np.column_stack([np.full(n, 2), 2 * np.arange(n), 2 * np.arange(n) + 1]))


class Canvas:
    """An offscreen top view of the floor plan with one coloured layer, a colour bar and a title.

    Layout in pixels: title band on top, colour bar band at the bottom, the
    floor plan in between at a uniform scale (parallel projection).
    """

    TOP, BOTTOM, MARGIN = 70, 100, 24

    def __init__(self, bounds, walls, exits, labels, floor, width):
        (x0, x1), (y0, y1) = bounds
        dx, dy = max(x1 - x0, 1e-12), max(y1 - y0, 1e-12)
        scale = min((width - 2 * self.MARGIN) / dx, 0.8 * width / dy)  # pixels per metre
        height = int(round(dy * scale)) + self.TOP + self.BOTTOM + 2 * self.MARGIN
        height += height % 2  # even sizes keep video encoders happy
        self.width, self.height = width, height
        self.plotter = p = pv.Plotter(off_screen=True, window_size=(width, height))
        p.set_background(BACKGROUND)
        size = max(dx, dy)
        if floor is not None:
            # under-plate: the bounding box in light grey, seen through the holes (obstacles);
            # the floor on it is seen where no coloured layer covers it (discs)
            plate = pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, -1e-3 * size), direction=(0, 0, 1),
                             i_size=dx, j_size=dy, i_resolution=1, j_resolution=1)
            p.add_mesh(plate, color=OBSTACLE, lighting=False)
            p.add_mesh(floor.translate((0, 0, -5e-4 * size)), color=FLOOR, lighting=False)
        for segments, colour, z, line in [(walls, WALL, 1e-3, width / 300), (exits, EXIT, 2e-3, width / 120)]:
            if len(segments):  # tubes: round joints, no gaps between segments
                p.add_mesh(_lines(segments, z * size), color=colour, line_width=max(2, line),
                           render_lines_as_tubes=True, lighting=False)
        for name, middle, normal in labels if len(labels) > 1 else ():  # name the exits when there are several
            inward = middle - normal * 14 / scale
            across = abs(normal[0]) > abs(normal[1])
            p.add_point_labels([[*inward, 3e-3 * size]], [name], font_size=max(8, width // 60), text_color=EXIT,
                               bold=True, shape=None, background_color="white", background_opacity=0.8,
                               show_points=False, always_visible=True,
                               justification_horizontal=("right" if normal[0] > 0 else "left") if across else "center",
                               justification_vertical="center" if across else ("top" if normal[1] > 0 else "bottom"))
        self.text = p.add_text("", position=(self.MARGIN, height - self.TOP + 6), font_size=max(10, width // 75),
                               color=TEXT)
        self.layer = self.outline = None
        camera = p.camera
        camera.parallel_projection = True
        world_height = height / scale
        centre_y = (y0 + y1) / 2 + (height / 2 - (self.BOTTOM + self.MARGIN + dy * scale / 2)) / scale
        camera.focal_point = ((x0 + x1) / 2, centre_y, 0.0)
        camera.position = ((x0 + x1) / 2, centre_y, 10 * size)
        camera.up = (0, 1, 0)
        camera.parallel_scale = world_height / 2
        p.renderer.ResetCameraClippingRange()

    def show(self, mesh, name, clim, cmap, bar_title):
        """Colour ``mesh`` by its array ``name`` (first call adds the layer, later calls replace its data)."""
        if self.layer is None:
            w, h, bar_height = self.width, self.height, 50
            bar = dict(title=bar_title, vertical=False, n_labels=tick_count(clim[1]), fmt="%.3g", color=TEXT,
                       position_x=0.2, width=0.6, position_y=8 / h, height=bar_height / h,
                       label_font_size=max(10, w // 45), unconstrained_font_size=True)
            self.layer = self.plotter.add_mesh(mesh, scalars=name, clim=clim, cmap=cmap, lighting=False,
                                               scalar_bar_args=bar, interpolate_before_map=False)
            # VTK lays the bar title over the labels: labels go below the bar, the title is our own text
            scalar_bar = self.plotter.scalar_bars[bar_title]
            scalar_bar.SetTitle("")
            scalar_bar.SetTextPositionToPrecedeScalarBar()
            scalar_bar.SetBarRatio(0.45)
            title = self.plotter.add_text(bar_title, position=(w / 2, 8 + bar_height + 6),
                                          font_size=max(9, w // 90), color=TEXT)
            title.prop.justification_horizontal = "center"
        else:
            self.layer.mapper.dataset = mesh
            self.layer.mapper.SetScalarRange(*clim)

    def show_discs(self, frame, clim):
        """Discs of a micro frame coloured by their pressure, with outlines."""
        fill, outline = _discs(frame)
        self.show(fill, "pressure", clim, CMAPS["pressure"], DISC_PRESSURE_TITLE)
        if self.outline is not None:
            self.plotter.remove_actor(self.outline)
        self.outline = self.plotter.add_mesh(outline, color=TEXT, line_width=1, lighting=False)

    def title(self, text):
        self.text.input = text

    def image(self):
        self.plotter.render()
        return self.plotter.screenshot(return_img=True)

    def save(self, path):
        self.plotter.render()
        self.plotter.screenshot(str(path))

    def close(self):
        self.plotter.close()


#: colour-bar maxima (mantissa) and their number of round intervals
NICE = ((1, 4), (1.2, 4), (1.5, 3), (2, 4), (2.5, 5), (3, 3), (4, 4), (5, 5), (6, 3), (8, 4), (10, 4))


def nice_top(value):
    """The smallest colour-bar maximum >= value with round ticks (1, 1.2, 1.5, 2, 2.5, ... x 10^k)."""
    if not value > 0:
        return 1.0
    unit = 10.0 ** np.floor(np.log10(value))
    return next(m * unit for m, _ in NICE if m * unit >= value * (1 - 1e-12))


def tick_count(top):
    """Number of colour-bar labels on [0, top]: round steps when top is a nice number, else 5."""
    mantissa = top / 10.0 ** np.floor(np.log10(top))
    return next((n + 1 for m, n in NICE if np.isclose(mantissa, m)), 5)


def _bounds(points):
    return (points[:, 0].min(), points[:, 0].max()), (points[:, 1].min(), points[:, 1].max())


def _discs(frame):
    """Disc fill (coloured by pressure) and outlines as glyphs of a unit polygon scaled by the radius."""
    centres = pv.PolyData(np.asarray(frame.points, float))
    for name in ("radius", "pressure"):
        centres.point_data[name] = (np.asarray(frame.point_data[name], float) if name in frame.point_data
                                    else np.zeros(frame.n_points))
    unit = pv.Polygon(center=(0, 0, 0), radius=1.0, normal=(0, 0, 1), n_sides=24)
    fill = centres.glyph(geom=unit.triangulate(), scale="radius", orient=False, factor=1.0)
    outline = centres.glyph(geom=unit.extract_feature_edges(), scale="radius", orient=False, factor=1.0)
    return fill, outline


def density_title(rho_max):
    return "density (people/m^2)" if rho_max != 1 else "density (rho / rho_max)"


PRESSURE_TITLE = "pressure p (m^2/s)"  # u = U - grad p: p has units of speed x length
DISC_PRESSURE_TITLE = "pressure: sum of contact multipliers (m/s)"  # u + B^T lambda = U


class Scene:
    """The floor plan of a run (from its mesh, else from its frames) and its bounds."""

    def __init__(self, run):
        plan = floor_plan(run)
        stem = "solution" if "solution" in run.frames else "discs"
        first = run.read(stem, 0)
        if plan is None:
            if stem == "solution":
                edges = first.extract_feature_edges(boundary_edges=True, feature_edges=False,
                                                    manifold_edges=False, non_manifold_edges=False)
                walls = np.asarray(edges.points)[edges.lines.reshape(-1, 3)[:, 1:], :2]
            else:
                walls = np.zeros((0, 2, 2))
            plan = walls, np.zeros((0, 2, 2)), [], first if stem == "solution" else None
        self.walls, self.exits, self.labels, self.floor = plan
        points = np.concatenate([self.walls.reshape(-1, 2), self.exits.reshape(-1, 2)])
        if not len(points):
            points = np.asarray(first.points)[:, :2]
        self.bounds = _bounds(points)

    def canvas(self, width):
        return Canvas(self.bounds, self.walls, self.exits, self.labels, self.floor, width)


def frame_index(series, times, directory):
    """Indices of the frames nearest to the given times (each must lie in the frames' time range)."""
    t = np.array([s[0] for s in series])
    for value in times:
        if not t[0] - 1e-9 <= value <= t[-1] + 1e-9:
            raise InputError(directory, "--times", value,
                             f"outside the time range of the frames [{t[0]:g}, {t[-1]:g}] s")
    return sorted({int(np.argmin(np.abs(t - value))) for value in times})


def default_times(run, series):
    """A few evenly spaced times from the start until the crowd is down to PICTURE_REMAINING."""
    t_end = series[-1][0]
    t_crowd = run.time_remaining(PICTURE_REMAINING)
    if t_crowd is not None:
        t_end = min(t_end, t_crowd)
    return list(np.linspace(series[0][0], t_end, DEFAULT_PICTURES))


def _stamp(t, series):
    """'t0012.5' for t = 12.5 s: four integer digits and the fewest decimals that write the frame times
    exactly (but the last, which may end early) and keep them apart: names sort in time order."""
    times = np.array([s[0] for s in series])
    decimals = next((d for d in range(7) if np.allclose(np.round(times[:-1], d), times[:-1], rtol=0, atol=1e-9)
                     and len(np.unique(np.round(times, d))) == len(times)), 6)
    return f"t{t:0{4 + decimals + (decimals > 0)}.{decimals}f}"


def pictures(run, scene, times, out):
    """density/pressure (macro) and discs (micro) PNGs at the frames nearest to ``times``."""
    written = []
    for stem, series in run.frames.items():
        chosen = frame_index(series, times if times else default_times(run, series), run.directory)
        frames = [run.read(stem, k) for k in chosen]
        if stem == "solution":
            fields = [f for f in ("density", "pressure") if f in frames[0].cell_data]
            for field in fields:
                if field == "density":
                    clim, bar = (0.0, run.rho_max), density_title(run.rho_max)
                else:
                    top = max(float(np.max(f.cell_data[field])) for f in frames)
                    clim, bar = (0.0, nice_top(top)), PRESSURE_TITLE
                canvas = scene.canvas(PICTURE_WIDTH)
                for k, frame in zip(chosen, frames):
                    t = series[k][0]
                    canvas.show(frame, field, clim, CMAPS[field], bar)
                    canvas.title(f"{run.title}\n{field} at t = {t:.4g} s")
                    written.append(out / f"{field}_{_stamp(t, series)}.png")
                    canvas.save(written[-1])
                canvas.close()
        else:
            written += _disc_pictures(run, scene, series, chosen, frames, out)
    return written


def _disc_range(frames):
    return 0.0, nice_top(max((float(np.max(f.point_data["pressure"])) for f in frames
                              if "pressure" in f.point_data and f.n_points), default=0.0))


def _disc_pictures(run, scene, series, chosen, frames, out):
    written, clim = [], _disc_range(frames)
    canvas = scene.canvas(PICTURE_WIDTH)
    for k, frame in zip(chosen, frames):
        t = series[k][0]
        canvas.show_discs(frame, clim)
        canvas.title(f"{run.title}\n{frame.n_points} discs at t = {t:.4g} s")
        written.append(out / f"discs_{_stamp(t, series)}.png")
        canvas.save(written[-1])
    canvas.close()
    return written


def animation(run, scene, out, mp4=False, quiet=True):
    """density.gif (discs.gif for micro runs), or .mp4, with the frames until the crowd is almost gone;
    returns its path (None without density frames)."""
    import imageio.v2 as imageio
    from tqdm import tqdm

    stem = "solution" if "solution" in run.frames else "discs"
    if stem == "solution" and "density" not in run.read(stem, 0).cell_data:
        log.warning("no density in the frames ([output].fields): no animation")
        return None
    series = run.frames[stem]
    t = np.array([s[0] for s in series])
    t_stop = run.time_remaining(ANIMATION_REMAINING)
    last = int(np.searchsorted(t, t_stop)) if t_stop is not None else len(t) - 1
    chosen = np.unique(np.round(np.linspace(0, min(last, len(t) - 1),
                                            min(last + 1, ANIMATION_FRAMES))).astype(int))
    name = "density" if stem == "solution" else "discs"
    path = out / f"{name}.{'mp4' if mp4 else 'gif'}"
    seconds = float(np.clip(ANIMATION_SECONDS / len(chosen), 0.05, 0.5))
    canvas = scene.canvas(ANIMATION_WIDTH)
    images = []
    clim = _disc_range([run.read(stem, k) for k in chosen]) if stem == "discs" else (0.0, run.rho_max)
    for k in tqdm(chosen, disable=quiet, delay=2.0, desc=f"animation {path.name}", unit="frame"):
        frame = run.read(stem, k)
        if stem == "solution":
            canvas.show(frame, "density", clim, CMAPS["density"], density_title(run.rho_max))
            canvas.title(f"{run.title}\ndensity at t = {t[k]:.1f} s")
        else:
            canvas.show_discs(frame, clim)
            canvas.title(f"{run.title}\n{frame.n_points} discs at t = {t[k]:.1f} s")
        images.append(canvas.image())
    canvas.close()
    if mp4:
        imageio.mimwrite(path, images, fps=1.0 / seconds, macro_block_size=2)
    else:
        imageio.mimwrite(path, images, duration=1000 * seconds, loop=0)
    return path


def _rate(time, cumulative, width):
    """Mean rate of a cumulative curve over time bins of about ``width``: (bin centres, rate)."""
    time, cumulative = np.r_[0.0, time], np.r_[0.0, cumulative]
    edges = np.linspace(0.0, time[-1], max(1, int(round(time[-1] / width))) + 1)
    values = np.interp(edges, time, cumulative)
    return 0.5 * (edges[1:] + edges[:-1]), np.diff(values) / np.diff(edges)


def curves(run, out):
    """curves.png: people inside/evacuated, flow rate per exit, max pressure, saturated area vs time."""
    from matplotlib.figure import Figure

    h = run.history
    if not h or not len(h.get("time", ())):
        log.warning("no history.csv rows in %s: no curves", run.directory)
        return None
    t = h["time"]
    micro = "count" in h
    unit = "people" if micro or run.rho_max != 1 else "rho_max m^2"
    t_gone = run.time_remaining(CURVES_REMAINING)
    t_show = min(t[-1], 1.15 * t_gone) if t_gone else t[-1]
    fig = Figure(figsize=(11, 7.5), layout="constrained")
    fig.suptitle(run.title if t_show == t[-1] else
                 f"{run.title}\n(shown until {100 * (1 - CURVES_REMAINING):g}% have left; "
                 f"the run goes on to t = {t[-1]:.4g} s)")
    ax = fig.subplots(2, 2, sharex=True)

    a = ax[0, 0]
    a.plot(t, h["count" if micro else "mass"], label="inside", color="#d7301f", lw=2)
    a.plot(t, h["evacuated"], label="evacuated", color="#2b8cbe", lw=2)
    a.set(ylabel="people" if unit == "people" else f"people ({unit})", title="people inside and evacuated")
    a.legend()

    a = ax[0, 1]
    exits = [c for c in h if c.startswith("evacuated_")]
    width = max(t_show / 80, 2 * float(np.median(np.diff(np.r_[0.0, t]))))  # bins of a few steps at least
    for column in exits:
        a.plot(*_rate(t, h[column], width), drawstyle="steps-mid", lw=2, label=column[len("evacuated_"):])
    if len(exits) != 1:
        a.plot(*_rate(t, h["evacuated"], width), drawstyle="steps-mid", color="k", lw=1.2,
               ls="--" if exits else "-", label="all exits")
    a.set(ylabel=f"flow rate ({unit}/s)", title="exit flow rate")
    a.legend()

    for a, (column, title, ylabel) in zip(ax[1], [
            ("contacts", "contacts", "active contacts") if micro else
            ("max_pressure", "max pressure", "max p (m^2/s)"),
            ("max_overlap", "max overlap", "overlap (m)") if micro else
            ("saturated_area", "saturated area (rho = rho_max)", "area (m^2)")]):
        if column in h:
            a.plot(t, h[column], color="#54278f", lw=1.5)
        a.set(title=title, ylabel=ylabel, xlabel="time (s)")
    for a in ax.flat:
        a.grid(alpha=0.3)
        a.set_xlim(0, t_show)
        a.set_ylim(bottom=0)
    path = out / "curves.png"
    fig.savefig(path, dpi=110)
    return path


def plot_run(directory, times=None, animate=True, out=None, mp4=False, quiet=True):
    """Write the pictures, animation and curves of a run; returns the written paths."""
    run = RunOutput(directory)
    if animate and mp4 and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise InputError(run.directory, "--mp4", True,
                         "MP4 needs imageio-ffmpeg (pip install imageio-ffmpeg); the default GIF does not")
    out = Path(out) if out is not None else run.directory
    out.mkdir(parents=True, exist_ok=True)
    scene = Scene(run)
    written = pictures(run, scene, times, out)
    written += [animation(run, scene, out, mp4, quiet) if animate else None, curves(run, out)]
    return [path for path in written if path is not None]
