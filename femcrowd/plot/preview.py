"""A picture of a case before any run (``femcrowd plot CASE_DIR``): the scene as a run builds it.

The scene comes from driver/scene.py (``build_scene``: the same checks as ``femcrowd run``, nothing run,
nothing written but the picture): walls in grey, each exit in green (red and dashed when closed at t = 0)
named with its schedule and capacity, the sources (entrances) in blue with their flow and span, the
measurement lines (an arrow: the direction counted positive) and areas in purple, and the initial crowd:
the density of a macro case (colour map), the discs of a micro case (a colour per population), with
the number of people in the title. Matplotlib, not the pyvista canvas of the run pictures: a preview is one
picture, and its labels are text artists a test can read.
"""

from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon
from matplotlib.tri import Triangulation

from ..case.units import counts_people, crowd_unit, density_title
from ..driver.populations import disc_populations, initial_densities
from ..driver.scene import build_scene, initial_discs
from ..files import make_directory, save_figure
from .canvas import CMAPS, EXIT, FLOOR, OBSTACLE, POPULATION_CMAPS, TEXT, WALL
from .levels import Levels

CLOSED, SOURCE, MEASURE = "#d7301f", "#2b6cb0", "#7b3294"


def _span(a, b):
    return f"{a:g}-{b:g} s" if np.isfinite(b) else f"from {a:g} s"


def schedule_text(door) -> str:
    """'always open', 'closed', or 'open 0-10 s, from 15 s' from a door's spans."""
    if door.spans is None:
        return "always open"
    return "open " + ", ".join(_span(a, b) for a, b in door.spans) if door.spans else "closed"


class _Plan:
    """What the preview draws the scene on: the floor plan, or a building's floors side by side (plot/levels.py)."""

    def __init__(self, domain):
        self.domain = domain
        self.levels = Levels(domain) if domain.z is not None else None

    def triangulation(self, mask=None) -> Triangulation:
        if self.levels is None:
            return Triangulation(*self.domain.points.T, self.domain.triangles, mask=mask)
        return Triangulation(*self.levels.corners().T, np.arange(3 * self.domain.ncells).reshape(-1, 3), mask=mask)

    def segments(self, facets):
        if self.levels is None:
            return self.domain.points[self.domain.mesh.facets[:, facets].T]
        return self.levels.segments(facets)

    def middle(self, facets):
        """The middle of a group of facets (where its label goes)."""
        middle = self.domain.midpoint[facets].mean(axis=0)
        return middle if self.levels is None else self.levels.point(facets, middle)

    def bounds(self):
        points = self.domain.points if self.levels is None else self.levels.corners()
        return points.min(axis=0), points.max(axis=0)


def _label(ax, text, middle, normal, colour, scale):
    """Text just inside the boundary at `middle` (outward `normal`), aligned away from the boundary."""
    across = abs(normal[0]) > abs(normal[1])
    ax.annotate(text, middle - normal * 0.02 * scale, color=colour, fontsize=9, fontweight="bold",
                ha=("right" if normal[0] > 0 else "left") if across else "center",
                va="center" if across else ("top" if normal[1] > 0 else "bottom"),
                bbox=dict(facecolor="white", alpha=0.8, edgecolor="none", pad=1.5), zorder=6)


def crowd(scene, plan):
    """The initial crowd: (people per population {name: count}, draw(ax, fig) -> legend handles), in the case's
    unit."""
    case, domain = scene.case, scene.domain
    rho = initial_densities(case, domain)   # (populations, cells), units of rho_max
    names = [p.name for p in scene.populations]
    rho_max = case["model"]["rho_max"]
    if case["model"]["type"] == "micro":
        q, r = initial_discs(case, domain, scene.boundary.at(0.0), rho.sum(axis=0) if len(rho) > 1 else None)
        population = disc_populations(case, domain, rho, q)
        counts = {name: int(np.sum(population == k)) for k, name in enumerate(names)}

        def draw(ax, fig):
            colours = np.array([matplotlib.colormaps[POPULATION_CMAPS[k % len(POPULATION_CMAPS)]](0.75)
                                for k in range(len(names))])
            ax.add_collection(EllipseCollection(2 * r, 2 * r, 0, units="xy", offsets=q, offset_transform=ax.transData,
                                                facecolors=colours[population], edgecolors=TEXT, linewidths=0.4,
                                                zorder=3))
            return [Line2D([], [], ls="", marker="o", markerfacecolor=c, markeredgecolor=TEXT, label=f"disc: {name}")
                    for name, c in zip(names, colours)] if len(names) > 1 else []
        return counts, draw

    counts = {name: float(domain.area @ rho[k]) * rho_max for k, name in enumerate(names)}

    def draw(ax, fig):
        total = rho.sum(axis=0) * rho_max
        tri = plan.triangulation(mask=total <= 0)
        if (total > 0).any():
            art = ax.tripcolor(tri, facecolors=total, cmap=CMAPS["density"], vmin=0, vmax=rho_max, zorder=2)
            fig.colorbar(art, ax=ax, shrink=0.8, label=density_title(counts_people(case.config)))
        return []
    return counts, draw


def scene_figure(case):
    """(the matplotlib Figure of a case's scene at t = 0, its number of people): the scene built as a run builds
    it, nothing run."""
    scene = build_scene(case)
    domain, boundary = scene.domain, scene.boundary
    plan = _Plan(domain)
    counts, draw = crowd(scene, plan)
    (x0, y0), (x1, y1) = plan.bounds()
    size = max(x1 - x0, y1 - y0)
    fig = Figure(figsize=(10, float(np.clip(9 * (y1 - y0) / max(x1 - x0, 1e-12) + 1.6, 4, 12))),
                 layout="constrained")
    ax = fig.subplots()
    ax.set_facecolor(OBSTACLE)   # holes (obstacles) show it; the floor is drawn over
    ax.tripcolor(plan.triangulation(), np.zeros(len(domain.triangles)),
                 cmap=matplotlib.colors.ListedColormap([FLOOR]), zorder=1)
    legend = draw(ax, fig)
    exits = np.zeros(len(domain.length), bool)
    for f in domain.exit_group.values():
        exits[f] = True
    ax.add_collection(LineCollection(plan.segments(~domain.interior & ~exits), colors=WALL, linewidths=2,
                                     capstyle="round", zorder=4))
    legend.append(Line2D([], [], color=WALL, lw=2, label="wall"))
    for point, text in zip(*plan.levels.captions()) if plan.levels is not None else ():   # each floor named
        ax.annotate(text, point, color=TEXT, fontsize=9, ha="center", va="top", xytext=(0, -4),
                    textcoords="offset points", zorder=6)
    rho_max, people = case["model"]["rho_max"], counts_people(case.config)
    for door in boundary.doors:
        closed = door.exit and not door.is_open(0.0)
        colour = CLOSED if closed else EXIT if door.exit else "#e08214"
        ax.add_collection(LineCollection(plan.segments(door.facets), colors=colour, linewidths=4,
                                         linestyles="--" if closed else "-", zorder=5))
        text = [door.name, schedule_text(door)] if door.exit else [f"{door.name} (interior door)"]
        if door.capped:
            text.append(f"capacity {door.capacity * rho_max:g} {'persons' if people else 'rho_max'}/(m s)")
        f = door.facets
        _label(ax, "\n".join(text), plan.middle(f), domain.normal[f].mean(axis=0), colour, size)
    legend += [Line2D([], [], color=colour, lw=4, ls=style, label=f"exit, {state} at t = 0")
               for colour, style, state in ((EXIT, "-", "open"), (CLOSED, "--", "closed"))
               if any(door.exit and door.is_open(0.0) == (state == "open") for door in boundary.doors)]
    for source in scene.sources:
        f = source.facets
        ax.add_collection(LineCollection(plan.segments(f), colors=SOURCE, linewidths=4, zorder=5))
        _label(ax, f"{source.boundary}: source {source.label('persons' if people else 'rho_max')}, "
                   f"{_span(source.start, source.end)}", plan.middle(f),
               domain.normal[f].mean(axis=0), SOURCE, size)
    if scene.sources:
        legend.append(Line2D([], [], color=SOURCE, lw=4, label="source (arrivals)"))
    for line in scene.lines:
        a, b = np.asarray(line.a, float), np.asarray(line.b, float)
        ax.plot(*np.column_stack([a, b]), color=MEASURE, lw=2, ls="--", zorder=6)
        middle, along = (a + b) / 2, b - a
        right = np.array([along[1], -along[0]]) / np.linalg.norm(along)   # the side counted positive
        reach = min(0.5 * np.linalg.norm(along), 0.04 * size)
        ax.annotate("", middle + reach * right, middle - reach * right, zorder=6,   # across the line
                    arrowprops=dict(arrowstyle="-|>", color=MEASURE, lw=2, mutation_scale=14))
        ax.annotate(line.name, middle + reach * right, color=MEASURE, fontsize=9, ha="left", va="bottom",
                    xytext=(4, 4), textcoords="offset points", zorder=6)   # at the arrow's head
    for area in scene.areas:
        ax.add_patch(Polygon(np.asarray(area.polygon.exterior.coords), closed=True, facecolor=MEASURE, alpha=0.15,
                             edgecolor=MEASURE, lw=1.5, zorder=3))
        (left, _, right, top) = area.polygon.bounds   # at its top, clear of the doors its side may touch
        ax.annotate(area.name, ((left + right) / 2, top), color=MEASURE, fontsize=9, ha="center", va="top",
                    xytext=(0, -3), textcoords="offset points", zorder=6)
    if scene.lines:
        legend.append(Line2D([], [], color=MEASURE, lw=2, ls="--",
                             label="counting line (the arrow across it: counted positive)"))
    if scene.areas:
        legend.append(Patch(facecolor=MEASURE, alpha=0.3, edgecolor=MEASURE, label="measurement area"))
    ax.set_aspect("equal")
    margin = 0.02 * size
    ax.set(xlim=(x0 - margin, x1 + margin), ylim=(y0 - margin, y1 + margin), xlabel="x (m)", ylabel="y (m)")
    ax.legend(handles=legend, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=min(len(legend), 4),
              fontsize=8, frameon=False)   # below the axes: it covers no door
    unit = "people" if case["model"]["type"] == "micro" else crowd_unit(people)
    total = sum(counts.values())
    amount = (lambda n: f"{n:.0f}") if unit == "people" else (lambda n: f"{n:.4g}")  # noqa: E731
    crowd_text = f"{amount(total)} {unit}" + (" (" + ", ".join(f"{name} {amount(n)}" for name, n in counts.items())
                                              + ")" if len(counts) > 1 else "")
    fig.suptitle(f"{case['title']}\nscene at t = 0 ({case['model']['type']} model): {crowd_text}"
                 + (", and arrivals" if scene.sources else ""), fontsize=11)
    return fig, total


def preview(case, out=None) -> tuple[Path, float]:
    """Write the scene of a case to OUT/<case directory name>-preview.png (OUT: the current directory by
    default); (the path, the number of people at t = 0)."""
    fig, total = scene_figure(case)
    directory = make_directory(out) if out is not None else Path.cwd()
    return save_figure(fig, directory / f"{case.file.parent.name}-preview.png"), total
