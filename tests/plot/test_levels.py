"""The pictures of a building: its floors side by side (plot/levels.py, docs/floors.md)."""

import numpy as np
import pytest
import pyvista as pv

from femcrowd import load_case, run
from femcrowd.mesh import load_domain
from femcrowd.plot import plot_run
from femcrowd.plot.levels import GAP, Levels
from femcrowd.plot.preview import scene_figure

from ..support import CASES, MESHES


def test_the_floors_of_the_three_storey_building_lie_side_by_side_each_stair_with_its_head():
    domain = load_domain(MESHES / "three_storeys.msh", ["exit"])
    levels = Levels(domain)
    assert levels.names == [["ground"], ["first"], ["second"]] and levels.step == pytest.approx(10 * (1 + GAP))
    cells = domain.mesh.subdomains
    for name, level in (("ground", 0), ("first", 1), ("stair_01", 1), ("second", 2), ("stair_12", 2)):
        assert np.all(levels.shift[cells[name]] == level * levels.step), name
    floor = levels.cells(pv.PolyData.from_regular_faces(np.column_stack([domain.points, domain.z]), domain.triangles))
    x = np.asarray(floor.points)[:, 0]
    assert floor.n_cells == domain.ncells and np.all(np.asarray(floor.points)[:, 2] == 0)   # a top view
    assert (x.min(), x.max()) == pytest.approx((0.0, 2 * levels.step + 10.0))
    # the areas are the plan's (a top view), each triangle moved as a whole
    assert floor.compute_cell_sizes().cell_data["Area"].sum() == pytest.approx(60 - 6 + 60 - 12 + 60 - 6 + 2 * 6)
    points, texts = levels.captions()   # each floor named under its panel
    assert texts == ["ground (z = 0 m)", "first (z = 3 m)", "second (z = 6 m)"]
    assert np.allclose(points, [(5 + k * levels.step, 0.0) for k in range(3)])
    walls = levels.segments(domain.f2t[1] < 0)
    assert walls[..., 0].max() == pytest.approx(2 * levels.step + 10.0)


def test_the_pictures_of_a_building_run(tmp_path):
    run(load_case(CASES / "corridor-stair", ["time.end=4", "output.every=2"]), tmp_path / "out")
    written = plot_run(tmp_path / "out", animate=False)
    names = {p.name for p in written}
    assert {"density_t0000.png", "density_t0004.png", "curves.png"} <= names, names


def test_the_preview_of_a_building_draws_each_floor_beside_the_others():
    fig, people = scene_figure(load_case(CASES / "three-storeys"))
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert {"ground (z = 0 m)", "first (z = 3 m)", "second (z = 6 m)"} <= set(texts)
    assert ax.get_xlim()[1] > 2 * 10 * (1 + GAP) + 10 and people == pytest.approx(0.6 * (48 + 54))
