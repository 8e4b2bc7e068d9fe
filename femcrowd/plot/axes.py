"""A run's floor plan on matplotlib axes : the walls, the exits with their names, the doors between
rooms; used by the level-of-service map (plot/measurements.py) and the report (femcrowd/report/)."""

import numpy as np

from .canvas import EXIT, WALL

INTERIOR = "#e6550d"    # a door with a capacity between two rooms
ENTRANCE = "#3182bd"    # a boundary group people arrive through ([[sources]])

#: Fruin's levels of service for walkways (Fruin 1971): upper densities (persons/m^2) of A..E, F above, colours
FRUIN = (0.31, 0.43, 0.72, 1.08, 2.17)
FRUIN_COLOURS = ("#1a9850", "#91cf60", "#d9ef8b", "#fee08b", "#fc8d59", "#d73027")


def _side(n, low, high):
    """The alignment of a label placed along the outward normal component n."""
    return low if n < -0.5 else high if n > 0.5 else "center"


def draw_doors(a, plan, t=0.0, names=None, entrances=()):
    """The walls and open exits of time t (plot/pictures.py FloorPlan) on the axes a, each exit labelled with its name
    or names[name]; the doors between rooms that have a capacity (in INTERIOR) and the boundary groups named in
    `entrances` (in ENTRANCE) as well; a legend below."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    names = names or {}
    walls, exits, labels, _ = plan.doors(t)
    a.add_collection(LineCollection(walls, colors=WALL, linewidths=2, capstyle="round"))
    a.add_collection(LineCollection(exits, colors=EXIT, linewidths=4))
    for name, middle, normal in labels:
        a.annotate(names.get(name, name), middle, xytext=(6 * normal[0], 6 * normal[1]), textcoords="offset points",
                   color=EXIT, fontsize=9, fontweight="bold", ha=_side(normal[0], "right", "left"),
                   va=_side(normal[1], "top", "bottom"), annotation_clip=False)
    handles = [Line2D([], [], color=WALL, lw=2, label="wall"), Line2D([], [], color=EXIT, lw=4, label="exit")]
    interior = [door for door in plan.boundary.doors if not door.exit] if plan.boundary is not None else []
    for door in interior:
        a.add_collection(LineCollection(plan.boundary.segments(door.name), colors=INTERIOR, linewidths=4))
        middle = plan.boundary.domain.midpoint[door.facets].mean(axis=0)
        a.annotate(names.get(door.name, door.name), middle, xytext=(5, 5), textcoords="offset points",
                   color=INTERIOR, fontsize=9, fontweight="bold")
    if interior:
        handles.append(Line2D([], [], color=INTERIOR, lw=4, label="door with a capacity"))
    domain = plan.boundary.domain if plan.boundary is not None else None
    entrances = [name for name in dict.fromkeys(entrances) if domain is not None and name in domain.groups]
    for name in entrances:
        facets = domain.groups[name]
        a.add_collection(LineCollection(domain.points[domain.mesh.facets[:, facets].T], colors=ENTRANCE, linewidths=4))
        a.annotate(names.get(name, name), domain.midpoint[facets].mean(axis=0), xytext=(5, 5),
                   textcoords="offset points", color=ENTRANCE, fontsize=9, fontweight="bold")
    if entrances:
        handles.append(Line2D([], [], color=ENTRANCE, lw=4, label="entrance (source)"))
    a.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=len(handles), frameon=False)
    (x0, x1), (y0, y1) = plan.bounds
    margin = 0.03 * max(x1 - x0, y1 - y0)
    a.set(xlim=(x0 - margin, x1 + margin), ylim=(y0 - margin, y1 + margin), aspect="equal")
    a.set(xlabel="x (m)", ylabel="y (m)")


def cell_map(fig, a, points, triangles, values, cmap, norm, label):
    """A field per triangle (points (n, 2+), triangles (m, 3)) on the axes a, with its colour bar; returns the bar."""
    art = a.tripcolor(points[:, 0], points[:, 1], triangles, facecolors=values, cmap=cmap, norm=norm)
    return fig.colorbar(art, ax=a, shrink=0.8, label=label)


def fruin_map(fig, a, points, triangles, density):
    """Fruin's level of service of the cell densities (persons/m^2), with the bar of the levels."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    bounds = (0.0, *FRUIN, max(2 * FRUIN[-1], float(np.max(density, initial=0.0))))
    bar = cell_map(fig, a, points, triangles, density, ListedColormap(FRUIN_COLOURS),
                   BoundaryNorm(bounds, len(FRUIN_COLOURS)), "level of service: density (persons/m^2)")
    bar.set_ticks([(lo + hi) / 2 for lo, hi in zip(bounds[:-1], bounds[1:])])
    bar.ax.set_yticklabels([f"{level} ({lo:g}-{hi:g})" if level != "F" else f"{level} (> {lo:g})"
                            for level, lo, hi in zip("ABCDEF", bounds[:-1], bounds[1:])])
    return bar
