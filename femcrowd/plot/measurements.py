"""Pictures of measurements.csv (``femcrowd plot``, for runs with [measure] lines or areas):

- ``lines.png``: N-t curves (cumulative count of each line) and the flow through each line over time;
- ``areas.png``: mean density against mean speed in each area (one point per step);
- ``level_of_service.png`` (macro): Fruin's level of service of the maximum density each cell reached
  during the run (the ``max_density`` cell field of the last frame). Fruin (1971), walkways: A < 0.31,
  B < 0.43, C < 0.72, D < 1.08, E < 2.17 persons/m^2, F beyond; densities in persons/m^2 (rho_max in
  persons/m^2, e.g. 5.4).
"""

import numpy as np

from ..driver.reading import read_history
from ..files import save_figure

#: Fruin's levels of service for walkways: upper densities (persons/m^2) of A..E, F above, and their colours
FRUIN = (0.31, 0.43, 0.72, 1.08, 2.17)
FRUIN_COLOURS = ("#1a9850", "#91cf60", "#d9ef8b", "#fee08b", "#fc8d59", "#d73027")


def measurement_plots(run, out, plan) -> list:
    """The pictures of the run's measurements.csv (none when it has none); plan: the run's FloorPlan
    (plot/pictures.py), whose walls and exits the level-of-service map draws."""
    path = run.directory / "measurements.csv"
    if not path.is_file():
        return []
    m = read_history(path)
    written = []
    if any(c.endswith("_count") for c in m):
        written.append(lines(run, m, out / "lines.png"))
    if any(c.endswith("_density") for c in m):
        written.append(areas(run, m, out / "areas.png"))
    if "solution" in run.frames and "max_density" in run.frame("solution", -1).cell_data:
        written.append(level_of_service(run, plan, out / "level_of_service.png"))
    return written


def lines(run, m, path):
    from matplotlib.figure import Figure

    t = m["time"]
    names = [c[: -len("_count")] for c in m if c.endswith("_count")]
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    fig.suptitle(run.title)
    ax = fig.subplots(1, 2, sharex=True)
    width = max(t[-1] / 60, 2 * float(np.median(np.diff(t)))) if len(t) > 1 else 1.0
    edges = np.linspace(0.0, t[-1], max(1, int(round(t[-1] / width))) + 1)
    for name in names:
        ax[0].plot(t, m[f"{name}_count"], lw=2, label=name)
        counts = np.interp(edges, t, m[f"{name}_count"])   # flow as the mean rate over bins of a few steps
        ax[1].plot(0.5 * (edges[1:] + edges[:-1]), np.diff(counts) / np.diff(edges), drawstyle="steps-mid", lw=2,
                   label=name)
    ax[0].set(title="N-t: cumulative count (left to right)", ylabel="people", xlabel="time (s)")
    ax[1].set(title="flow through the line", ylabel="people/s", xlabel="time (s)")
    for a in ax:
        a.grid(alpha=0.3)
        a.legend()
    return save_figure(fig, path)


def areas(run, m, path):
    from matplotlib.figure import Figure

    names = [c[: -len("_density")] for c in m if c.endswith("_density")]
    fig = Figure(figsize=(6, 4.5), layout="constrained")
    a = fig.subplots()
    for name in names:
        rho, v = m[f"{name}_density"], m[f"{name}_speed"]
        some = rho > 0
        a.scatter(rho[some], v[some], s=8, alpha=0.6, label=name)
    a.set(title=f"{run.title}\nmean speed against mean density", xlabel="density (people/m^2)",
          ylabel="speed (m/s)")
    a.set_xlim(left=0)
    a.set_ylim(bottom=0)
    a.grid(alpha=0.3)
    a.legend()
    return save_figure(fig, path)


def level_of_service(run, plan, path):
    from matplotlib.collections import LineCollection
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from .canvas import EXIT, WALL

    frame = run.frame("solution", -1)
    triangles = frame.cells_dict["triangle"]
    density = np.asarray(frame.cell_data["max_density"][0]).ravel()
    fig = Figure(figsize=(9, 6), layout="constrained")
    a = fig.subplots()
    top = max(2 * FRUIN[-1], float(density.max()))
    norm = BoundaryNorm((0.0, *FRUIN, top), len(FRUIN_COLOURS))
    art = a.tripcolor(frame.points[:, 0], frame.points[:, 1], triangles, facecolors=density,
                      cmap=ListedColormap(FRUIN_COLOURS), norm=norm)
    bounds = (0.0, *FRUIN, top)
    bar = fig.colorbar(art, ax=a, shrink=0.8, ticks=[(lo + hi) / 2 for lo, hi in zip(bounds[:-1], bounds[1:])],
                       label="level: maximum density (persons/m^2)")
    bar.ax.set_yticklabels([f"{level} ({lo:g}-{hi:g})" if level != "F" else f"{level} (> {lo:g})"
                            for level, lo, hi in zip("ABCDEF", bounds[:-1], bounds[1:])])
    walls, exits, labels, _ = plan.doors(0.0)
    a.add_collection(LineCollection(walls, colors=WALL, linewidths=2, capstyle="round"))
    a.add_collection(LineCollection(exits, colors=EXIT, linewidths=4))
    for name, middle, normal in labels:
        side = lambda n, low, high: low if n < -0.5 else high if n > 0.5 else "center"  # noqa: E731 (outward)
        a.annotate(name, middle, xytext=(6 * normal[0], 6 * normal[1]), textcoords="offset points", color=EXIT,
                   fontsize=9, fontweight="bold", ha=side(normal[0], "right", "left"),
                   va=side(normal[1], "top", "bottom"), annotation_clip=False)
    a.legend(handles=[Line2D([], [], color=WALL, lw=2, label="wall"), Line2D([], [], color=EXIT, lw=4, label="exit")],
             loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, frameon=False)
    a.set_aspect("equal")
    fig.suptitle(run.title, fontsize=10)
    a.set(title="level of service (Fruin 1971, walkways) of the maximum density over the run",
          xlabel="x (m)", ylabel="y (m)")
    return save_figure(fig, path)
