"""Floor plans from CAD: a DXF drawing made here with ezdxf (and a WKT polygon) meshes through `femcrowd mesh`
and runs; bad drawings are refused with one line and exit code 2."""

import ezdxf
import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.mesh import load_domain


def drawing(path, outline="polyline", exit_line=((10, 2.5), (10, 3.5)), obstacles=(((7, 3), 0.5),),
            square=((2, 2), (3, 3))):
    """A 10 x 6 m room: its outline on "walls" (a closed polyline, or lines and an arc rounding the corner
    (0, 6)), circles and a square made of lines on "obstacles", a door on "exit" and one on "entrance"."""
    doc = ezdxf.new()
    msp = doc.modelspace()
    if outline == "polyline":
        msp.add_lwpolyline([(0, 0), (10, 0), (10, 6), (0, 6)], close=True, dxfattribs={"layer": "walls"})
    else:
        for a, b in [((0, 0), (10, 0)), ((10, 0), (10, 6)), ((10, 6), (1, 6))] + \
                ([((0, 5), (0, 0))] if outline != "open" else []):
            msp.add_line(a, b, dxfattribs={"layer": "walls"})
        msp.add_arc((1, 5), 1, 90, 180, dxfattribs={"layer": "walls"})   # (1, 6) -> (0, 5)
    for centre, radius in obstacles:
        msp.add_circle(centre, radius, dxfattribs={"layer": "obstacles"})
    (x0, y0), (x1, y1) = square
    for a, b in [((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))]:
        msp.add_line(a, b, dxfattribs={"layer": "obstacles"})
    msp.add_line(*exit_line, dxfattribs={"layer": "exit"})
    msp.add_line((0, 2), (0, 3), dxfattribs={"layer": "entrance"})
    doc.saveas(path)
    return path


@pytest.mark.parametrize("outline", ["polyline", "lines and an arc"])
def test_a_dxf_drawing_meshes_and_runs(tmp_path, outline):
    plan = drawing(tmp_path / "plan.dxf", outline)
    result = CliRunner().invoke(main, ["mesh", str(plan), "--size", "0.3"])
    assert result.exit_code == 0, result.output
    domain = load_domain(tmp_path / "plan.msh", ["exit"])
    groups = {name: domain.length[f].sum() for name, f in domain.groups.items()}
    assert groups["exit"] == pytest.approx(1.0) and groups["entrance"] == pytest.approx(1.0)
    holes = np.pi * 0.25 + 1.0
    room = 60.0 if outline == "polyline" else 60.0 - (1 - np.pi / 4)   # the rounded corner
    assert domain.area.sum() == pytest.approx(room - holes, rel=2e-3)    # circles as polygons of the size
    (tmp_path / "case.toml").write_text('[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["exit"]\n'
                                        '[initial]\ndensity = "0.8 * (x > 4)"\n[time]\nend = 2.0\n'
                                        '[[sources]]\nboundary = "entrance"\nflow = 0.4\n')
    run = Simulation(load_case(tmp_path)).run()
    assert run.summary["status"] == "completed" and run.history["evacuated"][-1] > 0
    assert run.history["inflow"][-1] == pytest.approx(0.4 * 1.0 * 2.0, rel=1e-12)


def test_a_wkt_polygon_meshes_with_its_exits_given(tmp_path):
    (tmp_path / "area.wkt").write_text("POLYGON ((0 0, 10 0, 10 6, 0 6, 0 0), (2 2, 3 2, 3 3, 2 3, 2 2))\n")
    result = CliRunner().invoke(main, ["mesh", str(tmp_path / "area.wkt"), "--exit", "door=10,2.5,10,3.5"])
    assert result.exit_code == 0, result.output
    domain = load_domain(tmp_path / "area.msh", ["door"])
    assert domain.area.sum() == pytest.approx(59.0) and domain.length[domain.groups["door"]].sum() == 1.0


BAD = {
    "open outline": (dict(outline="open"), "layer 'walls'", "open outline"),
    "exit not on the outline": (dict(exit_line=((9, 2.5), (9, 3.5))), "layer 'exit' LINE", "must lie on one"),
    "overlapping obstacles": (dict(obstacles=(((7, 3), 0.5), ((7.5, 3), 0.5))), "layer 'obstacles' CIRCLE",
                              "overlaps"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_drawings_are_refused_in_one_line(tmp_path, name):
    options, where, words = BAD[name]
    plan = drawing(tmp_path / "plan.dxf", **options)
    result = CliRunner().invoke(main, ["mesh", str(plan)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(plan) in lines[0] and where in lines[0] and words in lines[0], lines
    assert not (tmp_path / "plan.msh").exists()
