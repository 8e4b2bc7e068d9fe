"""Micro/macro comparison on the same scene (Maury, Roudneff-Chupin, Santambrogio, Venel 2011, last section).

The case is run twice, as a macro case and as a micro case (same mesh, exits,
desired velocity, initial density; the discs are sampled from the macro
initial density). Both runs write their usual outputs (``macro/``,
``micro/``); the comparison adds, at the common frame times:

- people inside vs time for both models: the macro mass is converted to
  people with the discs' count, i.e. macro rho = 1 corresponds to the packing
  density the discs actually reached (the normalisation of Maury et al. 2011);
- W2, the quadratic Wasserstein distance between the macro density and the
  discs (POT's exact network-simplex solver, both normalised to unit mass:
  it compares the shapes of the crowds still inside);
- ``comparison.csv``, ``evacuation.png`` and side-by-side pictures.
"""

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import ot  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402

from ..case import Case  # noqa: E402
from ..driver import run  # noqa: E402
from ..driver.output import prepare_output_dir  # noqa: E402
from ..driver.reading import read_frame, read_pvd  # noqa: E402
from ..files import replaced, save_figure  # noqa: E402


def compare(case: Case, out=None, force=False, quiet=False, pictures=4, threads: int = 1) -> dict:
    """Run both models into OUT/macro and OUT/micro, then write the comparison into OUT."""
    out_dir = prepare_output_dir(case.output_dir(out), case.file, force)
    runs = {}
    for model in ("macro", "micro"):
        config = {**case.config, "model": {**case["model"], "type": model}}
        runs[model] = run(Case(config, case.file), out_dir / model, force, quiet, threads=threads)
    macro = _frames(out_dir / "macro" / "solution.pvd")
    micro = _frames(out_dir / "micro" / "discs.pvd")
    count = runs["micro"].summary["initial_count"]
    area = runs["macro"].domain.area
    mass0 = area @ macro[0][1].cell_data["density"][0]
    rows = []
    for k, (t, discs) in enumerate(micro):  # the macro run stops earlier when its room is empty
        grid = macro[min(k, len(macro) - 1)][1]
        density = grid.cell_data["density"][0] if k < len(macro) else np.zeros_like(area)
        rows.append({"time": t, "macro_inside": count * (area @ density) / mass0,
                     "micro_inside": len(discs.points), "w2": _w2(grid, area, density, discs)})
    with replaced(out_dir / "comparison.csv", sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    _plot_evacuation(out_dir / "evacuation.png", rows, case["title"])
    step = max(1, min(len(macro), len(micro)) // pictures)
    for k in range(0, min(len(macro), len(micro)), step)[:pictures]:
        _plot_side_by_side(out_dir / f"side_by_side_t{macro[k][0]:07.2f}.png", macro[k], micro[k])
    return {"output_dir": str(out_dir), "rows": rows, "macro": runs["macro"].summary,
            "micro": runs["micro"].summary, "discs": count}


def _frames(pvd):
    """[(time, meshio mesh)] of a frame series."""
    return [(t, read_frame(Path(pvd).parent / name)) for t, name in read_pvd(pvd)]


def _w2(grid, area, density, discs):
    """W2 between the macro density (cell masses at centroids) and the discs (equal weights), with distances in
    space: on a building the floors are apart by their elevations (a chord, shorter than the walk between them)."""
    mass = area * density
    if mass.sum() <= 0 or len(discs.points) == 0:
        return float("nan")
    keep = mass > 1e-12 * mass.max()
    centroids = grid.points[grid.cells_dict["triangle"][keep]].mean(axis=1)
    a = mass[keep] / mass[keep].sum()
    b = np.full(len(discs.points), 1.0 / len(discs.points))
    cost = ot.dist(centroids, discs.points)  # squared Euclidean
    return float(np.sqrt(ot.emd2(a, b, cost, numItermax=10_000_000)))


def _plot_evacuation(path, rows, title):
    t = [r["time"] for r in rows]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    ax.plot(t, [r["macro_inside"] for r in rows], label="macro (density, people = mass x N / mass0)")
    ax.plot(t, [r["micro_inside"] for r in rows], label="micro (discs)", drawstyle="steps-post")
    ax.set(xlabel="time (s)", ylabel="people inside", title="Evacuation")
    ax.legend()
    ax2.plot(t, [r["w2"] for r in rows])
    ax2.set(xlabel="time (s)", ylabel="W2 (m)", title="W2(macro density, discs), normalised")
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _plot_side_by_side(path, macro_frame, micro_frame):
    (t, grid), (_, discs) = macro_frame, micro_frame
    p, tri = grid.points[:, :2], grid.cells_dict["triangle"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True)
    im = axes[0].tripcolor(p[:, 0], p[:, 1], tri, facecolors=grid.cell_data["density"][0],
                           cmap="YlOrRd", vmin=0, vmax=1)
    fig.colorbar(im, ax=axes[0], label="density (rho / rho_max)")
    axes[0].set_title(f"macro, t = {t:.2f} s")
    circles = [plt.Circle(xy[:2], r) for xy, r in zip(discs.points, discs.point_data["radius"])]
    pressure = discs.point_data["pressure"]
    coll = PatchCollection(circles, cmap="Blues", edgecolor="k", linewidth=0.3)
    coll.set_array(pressure)
    coll.set_clim(0, max(float(pressure.max()) if len(pressure) else 0, 1e-12))
    axes[1].add_collection(coll)
    fig.colorbar(coll, ax=axes[1], label="contact pressure (sum of multipliers)")
    axes[1].set_title(f"micro, t = {t:.2f} s, {len(discs.points)} discs")
    for ax in axes:
        ax.triplot(p[:, 0], p[:, 1], tri, color="0.9", linewidth=0.2)
        ax.set_aspect("equal")
        ax.set_xlim(p[:, 0].min(), p[:, 0].max())
        ax.set_ylim(p[:, 1].min(), p[:, 1].max())
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
