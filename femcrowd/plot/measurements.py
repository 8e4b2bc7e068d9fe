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
from .axes import draw_doors, fruin_map


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
    from matplotlib.figure import Figure

    frame = run.frame("solution", -1)
    fig = Figure(figsize=(9, 6), layout="constrained")
    a = fig.subplots()
    fruin_map(fig, a, frame.points, frame.cells_dict["triangle"], np.asarray(frame.cell_data["max_density"][0]).ravel())
    draw_doors(a, plan)
    fig.suptitle(run.title, fontsize=10)
    a.set(title="level of service (Fruin 1971, walkways) of the maximum density over the run")
    return save_figure(fig, path)
