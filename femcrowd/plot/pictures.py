"""Pictures, animation and curves of a run directory (``femcrowd plot OUTDIR``).

Reads what a run wrote: ``solution.pvd`` (macro: cell data density, pressure)
or ``discs.pvd`` (micro: points with radius, pressure), ``history.csv`` and
``summary.json``; writes into ``OUTDIR/plots`` (or ``out``):

- ``density_tXXX.png`` and ``pressure_tXXX.png`` at the chosen times (macro),
  ``discs_tXXX.png`` (micro: discs coloured by their pressure);
- ``populations_tXXX.png`` for several populations (macro: each population in its own colour map, from
  the ``density_<name>`` arrays; micro: each disc in the colour of its population);
- ``density.gif`` (or ``.mp4`` with imageio-ffmpeg; micro: ``discs.gif``);
- ``curves.png``: people inside and evacuated, flow rate per exit, max
  pressure, saturated area (micro: contacts and max overlap) against time;
- with ``measurements.csv``: ``lines.png``, ``areas.png`` and ``level_of_service.png``
  (plot/measurements.py).

The floor plan comes from the run's mesh (file and exits recorded in
summary.json): walls in grey, exits in green, obstacles (holes) filled in
light grey. When the mesh cannot be found the boundary of the frames is
drawn, all as walls.
"""

import importlib.util
import logging
from pathlib import Path

import numpy as np

from ..case.units import counts_people, crowd_unit, density_title
from ..driver.ownership import reading
from ..driver.reading import RunDirectory
from ..errors import InputError
from ..files import make_directory, replaced, save_figure
from ..mesh import Boundary, file_checksum, load_domain
from .canvas import CMAPS, PRESSURE_TITLE, Canvas, bounds, nice_top, pv
from .levels import Levels
from .measurements import measurement_plots

log = logging.getLogger("femcrowd.plot")

PICTURE_WIDTH, ANIMATION_WIDTH = 1000, 640
DEFAULT_PICTURES = 4        # default times: evenly spaced until the crowd is down to ...
PICTURE_REMAINING = 0.05    # ... this fraction of the initial one
ANIMATION_REMAINING = 0.01  # the animation stops at the first frame below this fraction
ANIMATION_FRAMES = 80       # at most this many frames (evenly subsampled)
ANIMATION_SECONDS = 10.0    # target length of the animation
CURVES_REMAINING = 1e-3     # curves are shown until this fraction of the crowd is left


def read(run, stem, k):
    """Frame k of a run as a pyvista mesh (VTK's own reader: what is rendered), there and whole
    (RunDirectory.frame_file)."""
    return pv.read(run.frame_file(stem, k))


def floor_plan(run):
    """The run's doors over time (a Boundary with the case's [boundary.open] and [boundary.capacity]) and its floor
    (triangles, PolyData) from the run's mesh, or None when it cannot be found."""
    mesh, case = run.summary.get("mesh", {}), run.case
    file = Path(mesh.get("file", ""))
    if not mesh.get("file") or not file.is_file():
        log.warning("mesh of the run %s: all boundary edges drawn as walls",
                    f"not found ({file})" if mesh.get("file") else "unknown (no summary.json)")
        return None
    if mesh.get("sha256") and file_checksum(file) != mesh["sha256"]:
        log.warning("mesh %s changed since the run: walls and exits drawn from its current version", file)
    boundary = case.get("boundary", {})
    domain = load_domain(file, boundary.get("exits", []), case.get("mesh", {}).get("refine", 0))
    schedule = {name: spans for name, spans in boundary.get("open", {}).items() if name in domain.exit_group}
    rho_max = case.get("model", {}).get("rho_max", 1.0)
    capacity = {name: value / rho_max for name, value in boundary.get("capacity", {}).items() if name in domain.groups}
    floor = pv.PolyData.from_regular_faces(np.column_stack([domain.points, np.zeros(len(domain.points))]),
                                           domain.triangles)
    levels = Levels(domain) if domain.z is not None else None
    return Boundary(domain, schedule, capacity), floor if levels is None else levels.cells(floor), levels


class FloorPlan:
    """The floor plan of a run (from its mesh, else from its frames), its doors over time and its bounds."""

    def __init__(self, run):
        plan = floor_plan(run)
        stem = "solution" if "solution" in run.frames else "discs"
        first = read(run, stem, 0)
        self.boundary = self.levels = None
        if plan is None:
            if stem == "solution":
                edges = first.extract_feature_edges(boundary_edges=True, feature_edges=False,
                                                    manifold_edges=False, non_manifold_edges=False)
                self.walls = np.asarray(edges.points)[edges.lines.reshape(-1, 3)[:, 1:], :2]
            else:
                self.walls = np.zeros((0, 2, 2))
            self.floor = first if stem == "solution" else None
        else:
            self.boundary, self.floor, self.levels = plan
            self.walls = self._segments(self.boundary.at(0.0), "wall")
        walls, exits, _, _ = self.doors(0.0)
        points = np.concatenate([walls.reshape(-1, 2), exits.reshape(-1, 2)])
        if not len(points):
            points = np.asarray(first.points)[:, :2]
        self.bounds = bounds(points)

    @classmethod
    def of(cls, boundary):
        """The floor plan of a scene's doors over time (a Boundary), with no run directory (femcrowd.api)."""
        plan = cls.__new__(cls)
        plan.boundary, plan.floor, plan.levels = boundary, None, None
        plan.walls = boundary.at(0.0).segments("wall")
        walls, exits, _, _ = plan.doors(0.0)
        plan.bounds = bounds(np.concatenate([walls.reshape(-1, 2), exits.reshape(-1, 2)]))
        return plan

    def doors(self, t):
        """(walls, exits, labels, closed) at time t: the segments of the walls (closed exits among them) and of
        the open exits, a label [(name, midpoint, outward normal)] per exit ("name (closed)" when closed), the
        names of the closed exits."""
        if self.boundary is None:
            return self.walls, np.zeros((0, 2, 2)), [], []
        doors, d = self.boundary.at(t), self.boundary.domain
        closed = [name for name in doors.names if name not in doors.open]
        labels = [(name if name in doors.open else f"{name} (closed)", self._point(f, d.midpoint[f].mean(axis=0)),
                   d.normal[f].mean(axis=0)) for name, f in d.exit_group.items()]
        return self._segments(doors, "wall"), self._segments(doors, "exit"), labels, closed

    def frame(self, mesh):
        """A frame as the pictures draw it: a building's floors side by side (plot/levels.py), its discs with them."""
        if self.levels is None:
            return mesh
        return self.levels.discs(mesh) if "radius" in mesh.point_data else self.levels.cells(mesh)

    def _segments(self, doors, which):
        if self.levels is None:
            return doors.segments(which)
        return self.levels.segments(doors.wall if which == "wall" else doors.exit)

    def _point(self, facets, xy):
        return xy if self.levels is None else self.levels.point(facets, xy)

    def canvas(self, width):
        walls, exits, labels, _ = self.doors(0.0)
        canvas = Canvas(self.bounds, walls, exits, labels, self.floor, width)
        if self.levels is not None:
            canvas.captions(*self.levels.captions())
        return canvas

    def show(self, canvas, t):
        """Draw the doors of time t on the canvas; ' (closed: names)' for the title."""
        walls, exits, labels, closed = self.doors(t)
        canvas.doors(walls, exits, labels)
        return f" (closed: {', '.join(closed)})" if closed else ""


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


def pictures(run, plan, times, out):
    """density/pressure (macro) and discs (micro) PNGs at the frames nearest to ``times``."""
    written = []
    for stem, series in run.frames.items():
        chosen = frame_index(series, times if times else default_times(run, series), run.directory)
        frames = [plan.frame(read(run, stem, k)) for k in chosen]
        if stem == "solution":
            fields = [f for f in ("density", "pressure") if f in frames[0].cell_data]
            for field in fields:
                if field == "density":
                    clim, bar = (0.0, run.rho_max), density_title(counts_people(run.case))
                else:
                    top = max(float(np.max(f.cell_data[field])) for f in frames)
                    clim, bar = (0.0, nice_top(top)), PRESSURE_TITLE
                canvas = plan.canvas(PICTURE_WIDTH)
                for k, frame in zip(chosen, frames):
                    t = series[k][0]
                    canvas.show(frame, field, clim, CMAPS[field], bar)
                    canvas.title(f"{run.title}\n{field} at t = {t:.4g} s{plan.show(canvas, t)}")
                    written.append(out / f"{field}_{_stamp(t, series)}.png")
                    canvas.save(written[-1])
                canvas.close()
            written += _population_pictures(run, plan, series, chosen, frames, out)
        else:
            written += _disc_pictures(run, plan, series, chosen, frames, out)
    return written


def _population_pictures(run, plan, series, chosen, frames, out):
    """populations_tXXX.png: the density of each population in its own colour map (several populations)."""
    names = [name[len("density_"):] for name in frames[0].cell_data if name.startswith("density_")]
    if not names:
        return []
    written, canvas = [], plan.canvas(PICTURE_WIDTH)
    for k, frame in zip(chosen, frames):
        t = series[k][0]
        canvas.show_populations(frame, names, run.rho_max, density_title(counts_people(run.case)))
        canvas.title(f"{run.title}\n{', '.join(names)} at t = {t:.4g} s{plan.show(canvas, t)}")
        written.append(out / f"populations_{_stamp(t, series)}.png")
        canvas.save(written[-1])
    canvas.close()
    return written


def _disc_range(frames):
    return 0.0, nice_top(max((float(np.max(f.point_data["pressure"])) for f in frames
                              if "pressure" in f.point_data and f.n_points), default=0.0))


def _disc_pictures(run, plan, series, chosen, frames, out):
    """discs_tXXX.png (discs coloured by their pressure) and, for several populations, populations_tXXX.png
    (coloured by their population)."""
    written, clim = [], _disc_range(frames)
    names = list(run.summary.get("populations", {}))
    for stem in ("discs", "populations") if names else ("discs",):
        canvas = plan.canvas(PICTURE_WIDTH)
        for k, frame in zip(chosen, frames):
            t = series[k][0]
            if stem == "discs":
                canvas.show_discs(frame, clim)
            else:
                canvas.show_disc_populations(frame, names)
            canvas.title(f"{run.title}\n{frame.n_points} discs at t = {t:.4g} s{plan.show(canvas, t)}")
            written.append(out / f"{stem}_{_stamp(t, series)}.png")
            canvas.save(written[-1])
        canvas.close()
    return written


def animation(run, plan, out, mp4=False, quiet=True):
    """density.gif (discs.gif for micro runs), or .mp4, with the frames until the crowd is almost gone;
    returns its path (None without density frames)."""
    import imageio.v2 as imageio
    from tqdm import tqdm

    stem = "solution" if "solution" in run.frames else "discs"
    if stem == "solution" and "density" not in read(run, stem, 0).cell_data:
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
    canvas = plan.canvas(ANIMATION_WIDTH)
    images = []
    clim = _disc_range([read(run, stem, k) for k in chosen]) if stem == "discs" else (0.0, run.rho_max)
    for k in tqdm(chosen, disable=quiet, delay=2.0, desc=f"animation {path.name}", unit="frame"):
        frame, closed = plan.frame(read(run, stem, k)), plan.show(canvas, t[k])
        if stem == "solution":
            canvas.show(frame, "density", clim, CMAPS["density"], density_title(counts_people(run.case)))
            canvas.title(f"{run.title}\ndensity at t = {t[k]:.1f} s{closed}")
        else:
            canvas.show_discs(frame, clim)
            canvas.title(f"{run.title}\n{frame.n_points} discs at t = {t[k]:.1f} s{closed}")
        images.append(canvas.image())
    canvas.close()
    with replaced(path) as tmp:
        if mp4:
            imageio.mimwrite(tmp, images, fps=1.0 / seconds, macro_block_size=2)
        else:
            imageio.mimwrite(tmp, images, duration=1000 * seconds, loop=0)
    return path


def binned_rate(time, cumulative, width):
    """Mean rate of a cumulative curve (0 at t = 0) over time bins of about ``width`` from t = 0: (bin centres,
    rate); the curves of a run and the peak flows of its report (report/numbers.py)."""
    time, cumulative = np.r_[0.0, time], np.r_[0.0, cumulative]
    edges = np.linspace(0.0, time[-1], max(1, int(round(time[-1] / width))) + 1)
    values = np.interp(edges, time, cumulative)
    return 0.5 * (edges[1:] + edges[:-1]), np.diff(values) / np.diff(edges)


def _empty(h, column):
    """Is a history column missing, or zero for the whole run (max pressure and saturated area with a speed law
    that never saturates, contacts of discs that never touch)?"""
    return column not in h or not np.any(h[column])


def curves(run, out):
    """curves.png (curves_figure), or None without history rows."""
    fig = curves_figure(run)
    if fig is None:
        return None
    return save_figure(fig, out / "curves.png")


def curves_figure(run):
    """People inside/evacuated, flow rate per exit, and the max pressure and saturated area (micro: contacts and
    max overlap) vs time, the panels of these that are zero for the whole run left out."""
    from matplotlib.figure import Figure

    h = run.history
    if not h or not len(h.get("time", ())):
        log.warning("no history.csv rows in %s: no curves", run.directory)
        return None
    t = h["time"]
    micro = "count" in h
    unit = "people" if micro else crowd_unit(counts_people(run.case))
    t_gone = run.time_remaining(CURVES_REMAINING)
    t_show = min(t[-1], 1.15 * t_gone) if t_gone else t[-1]
    extra = [panel for panel in ([("contacts", "contacts", "active contacts"),
                                  ("max_overlap", "max overlap", "overlap (m)")] if micro else
                                 [("max_pressure", "max pressure", "max p (m^2/s)"),
                                  ("saturated_area", "saturated area (rho = rho_max)", "area (m^2)")])
             if not _empty(h, panel[0])]
    rows = 1 + (len(extra) > 0)
    fig = Figure(figsize=(11, 3.75 * rows + (rows == 1) * 0.5), layout="constrained")
    fig.suptitle(run.title if t_show == t[-1] else
                 f"{run.title}\n(shown until {100 * (1 - CURVES_REMAINING):g}% have left; "
                 f"the run goes on to t = {t[-1]:.4g} s)")
    ax = fig.subplots(rows, 2, sharex=True, squeeze=False)

    a = ax[0, 0]
    a.plot(t, h["count" if micro else "mass"], label="inside", color="#d7301f", lw=2)
    a.plot(t, h["evacuated"], label="evacuated", color="#2b8cbe", lw=2)
    a.set(ylabel=unit if unit == "people" else f"crowd ({unit})", title="people inside and evacuated")
    a.legend()

    a = ax[0, 1]
    populations = set(run.case.get("populations", {}))   # evacuated_<population> next to evacuated_<exit>
    exits = [c for c in h if c.startswith("evacuated_") and c[len("evacuated_"):] not in populations]
    width = max(t_show / 80, 2 * float(np.median(np.diff(np.r_[0.0, t]))))  # bins of a few steps at least
    for column in exits:
        a.plot(*binned_rate(t, h[column], width), drawstyle="steps-mid", lw=3.5, alpha=0.8, zorder=3,
               label=column[len('evacuated_'):])
    for k, name in enumerate(p for p in run.case.get("populations", {}) if f"evacuated_{p}" in h):
        # thin and dashed: the exits show beneath
        a.plot(*binned_rate(t, h[f"evacuated_{name}"], width), drawstyle="steps-mid", lw=1.3, ls="--", zorder=4,
               color=f"C{len(exits) + k}", label=f"population {name}")
    if len(exits) != 1:
        a.plot(*binned_rate(t, h["evacuated"], width), drawstyle="steps-mid", color="k", lw=1.2,
               ls="--" if exits else "-", label="all exits")
    a.set(ylabel=f"flow rate ({unit}/s)", title="exit flow rate")
    a.legend()

    for a, (column, title, ylabel) in zip(ax[1] if extra else (), extra):
        a.plot(t, h[column], color="#54278f", lw=1.5)
        a.set(title=title, ylabel=ylabel)
    bottom = [ax[-1, 0], ax[-1, 1]]
    if len(extra) == 1:   # the panel above the empty place shows the time axis
        ax[1, 1].remove()
        bottom[1] = ax[0, 1]
        ax[0, 1].xaxis.set_tick_params(labelbottom=True)
    for a in bottom:
        a.set_xlabel("time (s)")
    for a in fig.axes:
        a.grid(alpha=0.3)
        a.set_xlim(0, t_show)
        a.set_ylim(bottom=0)
    return fig


def plot_run(directory, times=None, animate=True, out=None, mp4=False, quiet=True) -> list:
    """Write the pictures, animation and curves of a run into out (default: directory/plots); returns
    the written paths. The directory is held for reading meanwhile (driver/ownership.py): a run in progress
    may be plotted, a new run into it is refused."""
    with reading(directory):
        return _plot_run(directory, times, animate, out, mp4, quiet)


def _plot_run(directory, times, animate, out, mp4, quiet) -> list:
    run = RunDirectory(directory)
    if animate and mp4 and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise InputError(run.directory, "--mp4", True,
                         "MP4 needs imageio-ffmpeg (pip install imageio-ffmpeg); the default GIF does not")
    out = make_directory(out) if out is not None else make_directory(run.directory / "plots", own=True)
    plan = FloorPlan(run)
    written = pictures(run, plan, times, out)
    written += [animation(run, plan, out, mp4, quiet) if animate else None, curves(run, out)]
    written += measurement_plots(run, out, plan)
    return [path for path in written if path is not None]
