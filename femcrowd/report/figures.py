"""The figures of a report and of the Python API (matplotlib, no window): a map of the floor plan with the density,
its level of service or the discs, and the doors; the N-t curves; each as a PNG data URI for a page with no outside
file (``data_uri``)."""

import base64
import io

import numpy as np
from matplotlib.figure import Figure

from ..case.units import counts_people, crowd_unit, density_title
from ..plot.axes import cell_map, draw_doors, fruin_map

DPI = 100


def data_uri(fig) -> str:
    """The figure as a base64 PNG data URI (RFC 2397)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def door_names(doors, rho_max) -> dict:
    """'exit: 1.2 m, 1.9 p/(m s)': the label of each door (mesh/boundary.py Door) on the plan."""
    return {door.name: f"{door.name}: {door.width:.3g} m"
            + (f", {door.capacity * rho_max:.3g} p/(m s)" if door.capped else "") for door in doors}


def map_figure(plan, t, title, case, cells=None, discs=None, names=None, level_of_service=False):
    """The floor plan (plot/pictures.py FloorPlan) at time t with its doors, and on it the density of the cells
    (points, triangles, density in the case's unit), Fruin's level of service of it, or the discs (xy, radius)."""
    from matplotlib.collections import EllipseCollection
    from matplotlib.colors import Normalize

    (x0, x1), (y0, y1) = plan.bounds   # the height of the plan at 5.5 in wide, with room for the bar and legend
    fig = Figure(figsize=(8, float(np.clip(5.5 * (y1 - y0) / max(x1 - x0, 1e-9) + 1.3, 3, 9))), layout="compressed")
    a = fig.subplots()
    if cells is not None:
        points, triangles, density = cells
        if level_of_service:
            fruin_map(fig, a, points, triangles, density)
        else:
            cell_map(fig, a, points, triangles, density, "YlOrRd",
                     Normalize(0.0, case.get("model", {}).get("rho_max", 1.0)), density_title(counts_people(case)))
    if discs is not None:
        xy, radius = discs
        a.add_collection(EllipseCollection(2 * radius, 2 * radius, np.zeros_like(radius), units="xy", offsets=xy,
                                           offset_transform=a.transData, facecolors="#d7301f", edgecolors="k",
                                           linewidths=0.3))
    draw_doors(a, plan, t, names, [source["boundary"] for source in case.get("sources", [])])
    a.set_title(f"{title} at t = {t:.4g} s")
    return fig


def frame_figure(run, plan, k, title, names=None, level_of_service=False):
    """Frame k of a run directory (driver/reading.py RunDirectory) as a map_figure."""
    stem = "solution" if "solution" in run.frames else "discs"
    t, frame = run.frames[stem][k][0], run.frame(stem, k)
    levels = plan.levels   # a building: its floors side by side, as the pictures draw them (plot/levels.py)
    if stem == "solution":
        density = np.asarray(frame.cell_data["density"][0]).ravel()
        if levels is None:
            cells = (frame.points, frame.cells_dict["triangle"], density)
        else:
            corners = levels.corners()
            cells = (corners, np.arange(len(corners)).reshape(-1, 3), density)
        discs = None
    else:
        radius = np.asarray(frame.point_data.get("radius", np.zeros(len(frame.points))), float)
        points = np.asarray(frame.points, float)
        if levels is not None:
            import pyvista as pv

            points = np.asarray(levels.discs(pv.PolyData(points)).points)
        cells, discs = None, (points[:, :2], radius)
    return map_figure(plan, t, title, run.case, cells, discs, names, level_of_service)


def nt_figure(history, case, curves, shares):
    """The N-t curves: people out in all and through each door against time; t50, t90, t99 marked."""
    h = history
    t, micro = h["time"], "count" in h
    unit = "people" if micro else crowd_unit(counts_people(case))
    fig = Figure(figsize=(9, 4.2), layout="constrained")
    a = fig.subplots()
    a.plot(t, h["evacuated"], color="k", lw=2.5, label="out (all exits)")
    a.plot(t, h["count" if micro else "mass"], color="#d7301f", lw=1.5, ls="--", label="inside")
    for k, (name, curve) in enumerate(curves.items()):
        a.plot(t, curve, lw=1.8, color=f"C{k}", label=f"through {name}")
    for name, value in shares.items():
        if np.isfinite(value):
            a.axvline(value, color="0.5", lw=0.8, ls=":")
            a.annotate(name, (value, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -12),
                       textcoords="offset points", fontsize=8, color="0.3")
    a.set(xlabel="time (s)", ylabel=unit, title="N-t: people inside, out, and through each door")
    a.set_xlim(0, t[-1])
    a.set_ylim(bottom=0)
    a.grid(alpha=0.3)
    a.legend(fontsize=8, loc="center right")
    return fig
