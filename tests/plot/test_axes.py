"""The floor plan on matplotlib axes (plot/axes.py): walls, exits, doors with a capacity and entrances, each in its
colour and named."""

import numpy as np
from matplotlib.colors import to_hex
from matplotlib.figure import Figure

from femcrowd.mesh import Boundary
from femcrowd.plot.axes import ENTRANCE, EXIT, INTERIOR, WALL, draw_doors
from femcrowd.plot.pictures import FloorPlan

from ..support import unit_square


def test_every_kind_of_door_in_its_colour_and_named():
    """The unit square, its right side the exit, its left side an entrance: the segments of exit and
    entrance (8 facets a side), the rest walls; names as labels; a legend entry per kind present."""
    domain = unit_square(4, ["right"])
    plan = FloorPlan.of(Boundary(domain))
    a = Figure().subplots()
    draw_doors(a, plan, 0.0, {"right": "right: 1 m"}, entrances=["left", "nowhere"])
    lines = {to_hex(c.get_colors()[0]): len(c.get_segments()) for c in a.collections}
    assert lines == {WALL: 24, EXIT: 8, ENTRANCE: 8}   # the entrance drawn over its wall
    assert INTERIOR not in lines
    assert {t.get_text() for t in a.texts} == {"right: 1 m", "left"}
    assert [t.get_text() for t in a.get_legend().get_texts()] == ["wall", "exit", "entrance (source)"]
    assert plan.bounds == ((0.0, 1.0), (0.0, 1.0)) and np.allclose(a.get_xlim(), (-0.03, 1.03))
