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


def office(path, scale=1.0, insunits=6, walls=(((5, 0), (5, 4)), ((5, 5), (5, 6))), exit_layer="exit",
           extra=True):
    """A 10 x 6 m office drawn in units of 1/scale m ($INSUNITS insunits): its outline a closed polyline on
    "walls", a partition at x = 5 drawn as LINEs on "walls" (default: a doorway between y = 4 and 5), an exit
    at x = 10 on `exit_layer`, an entrance at x = 0; with `extra`, a text on a layer "notes"."""
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = insunits
    msp = doc.modelspace()
    s = lambda *points: [(scale * x, scale * y) for x, y in points]   # noqa: E731
    msp.add_lwpolyline(s((0, 0), (10, 0), (10, 6), (0, 6)), close=True, dxfattribs={"layer": "walls"})
    for wall in walls:
        if len(wall) == 2:
            msp.add_line(*s(*wall), dxfattribs={"layer": "walls"})
        else:
            msp.add_lwpolyline(s(*wall), dxfattribs={"layer": "walls"})
    msp.add_line(*s((10, 0.5), (10, 1.5)), dxfattribs={"layer": exit_layer})
    msp.add_line(*s((0, 2), (0, 3)), dxfattribs={"layer": "entrance"})
    if extra:
        msp.add_text("office", dxfattribs={"layer": "notes"})
    doc.saveas(path)
    return path


def mesh(plan, *options):
    return CliRunner().invoke(main, ["mesh", str(plan), "--size", "0.4", *map(str, options)])


def one_line_error(result, *words):
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.strip().splitlines() if line.startswith("femcrowd: error: ")]
    assert len(lines) == 1 and "Traceback" not in result.output and all(w in lines[0] for w in words), lines
    return lines[0]


@pytest.mark.parametrize("scale, insunits, units", [(1000, 4, None), (100, 0, "cm"), (1 / 0.3048, 0, "ft"),
                                                    (1000, 6, "mm"), (1e-3, 7, None), (1e6, 13, None),
                                                    (0.1, 15, None)])
def test_units_from_insunits_or_given(tmp_path, scale, insunits, units):
    """A plan drawn in millimetres with $INSUNITS = 4, in centimetres or feet without units and --units,
    in mm with $INSUNITS wrongly saying m and --units mm, in km (7), microns (13) or decametres (15): the
    mesh is the 10 x 6 m office."""
    plan = office(tmp_path / "plan.dxf", scale, insunits)
    result = mesh(plan, *(["--units", units] if units else []))
    assert result.exit_code == 0, result.output
    domain = load_domain(tmp_path / "plan.msh")
    assert np.ptp(domain.points, axis=0) == pytest.approx([10, 6], rel=1e-9)
    assert domain.area.sum() == pytest.approx(60 - 0.1 * 5, rel=1e-9)    # the partition, 0.1 m thick, 5 m long
    assert domain.length[domain.groups["exit"]].sum() == pytest.approx(1.0, rel=1e-9)


def test_an_implausible_size_is_refused_before_meshing(tmp_path, monkeypatch):
    """The office in millimetres with $INSUNITS saying metres (10 km across: 3e9 triangles) and a 30 x 20 m hall
    in millimetres read as metres: one line naming the units and the --units to give, no mesh written, gmsh
    never started (meshing them would take hours); the same office read with --units km is too small."""
    from femcrowd.mesh import floorplan

    def never(*args, **kwargs):
        raise AssertionError("gmsh started on an implausible plan")
    monkeypatch.setattr(floorplan.gmsh, "initialize", never)
    line = one_line_error(mesh(office(tmp_path / "plan.dxf", 1000, 6)), "plan.dxf", "units = 'm ($INSUNITS = 6)'",
                          "1e+04 m x 6e+03 m", "--units mm")
    assert "triangles" in line
    hall = office(tmp_path / "hall.dxf", 3000, 0, walls=())
    one_line_error(mesh(hall), "hall.dxf", "unitless: taken as m", "3e+04 m x 1.8e+04 m",
                   "not the size of a building", "--units mm")
    one_line_error(mesh(office(tmp_path / "km.dxf"), "--units", "km"), "units = 'km (--units)'", "1e+04 m",
                   "--units m")
    one_line_error(mesh(hall, "--units", "parsec"), "--units = 'parsec'", "expected one of mm, cm")
    assert not list(tmp_path.glob("*.msh"))


def components(domain):
    """The number of edge-connected pieces of the mesh."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = domain.mesh.f2t[:, domain.mesh.f2t[1] >= 0]
    n = domain.mesh.t.shape[1]
    return connected_components(coo_matrix((np.ones(pairs.shape[1]), pairs), shape=(n, n)))[0]


def test_a_partition_with_a_doorway_is_a_wall_people_walk_around(tmp_path):
    """Two LINEs at x = 5 on the walls layer, a 1 m doorway between y = 4 and 5: a strip 0.1 m thick cut out of
    the floor, its sides wall facets; the floor stays one piece, and the walking distance from (1, 1) to the
    exit (x = 10, y in [0.5, 1.5]) goes through the doorway (10.6 m, against 9 m through the wall)."""
    from femcrowd.mesh.distance import exit_distance

    result = mesh(office(tmp_path / "plan.dxf"))
    assert result.exit_code == 0, result.output
    domain = load_domain(tmp_path / "plan.msh", ["exit"])
    m = domain.mesh
    wall = m.facets[:, domain.groups["wall"]]
    mid = domain.points[wall].mean(axis=0)
    sides = np.isclose(np.abs(mid[:, 0] - 5), 0.05) & (mid[:, 1] > 0) & (mid[:, 1] < 6)
    assert domain.length[domain.groups["wall"]][sides].sum() == pytest.approx(2 * 4 + 2 * 1, rel=1e-9)
    centroids = domain.points[domain.triangles].mean(axis=1)
    assert not (np.abs(centroids[:, 0] - 5) < 0.05).any() or \
        (np.abs(centroids[np.abs(centroids[:, 0] - 5) < 0.05, 1] - 4.5) < 0.5).all()   # only in the doorway
    assert components(domain) == 1
    d = exit_distance(domain.points, domain.triangles, m.facets[:, domain.groups["exit"]].T)
    assert np.isfinite(d).all()
    start = np.argmin(np.linalg.norm(domain.points - [1, 1], axis=1))
    through_door = np.linalg.norm(domain.points[start] - [4.95, 4]) + 0.1 + np.hypot(4.95, 2.5)
    assert d[start] == pytest.approx(through_door, rel=0.02) and d[start] > 10


@pytest.mark.parametrize("walls, words", [
    ((((5, 0), (5, 6)),), ["walls = '1 walls'", "cut the plan into 2 parts"]),
    ((((5, 0), (5, 7)),), ["layer 'walls' LINE", "must lie inside the outer boundary"]),
    ((((2, 0), (2, 3), (5, 3), (5, 0)),), ["cut the plan into 2 parts (50.5, 8.56 m^2)", "leave a doorway"])])
def test_partitions_that_close_a_room_or_leave_the_plan_are_refused(tmp_path, walls, words):
    one_line_error(mesh(office(tmp_path / "plan.dxf", walls=walls)), "plan.dxf", *words)
    assert not (tmp_path / "plan.msh").exists()


def test_an_open_polyline_partition_and_a_line_joined_to_it(tmp_path):
    """An L drawn as an open LWPOLYLINE from the bottom wall, and a LINE going on from its end to 1 m short of
    the top wall: the joints closed (the floor loses exactly the 0.1 m strips of the 8 m drawn), the floor
    one piece."""
    result = mesh(office(tmp_path / "plan.dxf", walls=(((3, 0), (3, 4), (6, 4)), ((6, 4), (6, 5)))))
    assert result.exit_code == 0, result.output
    domain = load_domain(tmp_path / "plan.msh")
    assert components(domain) == 1
    assert domain.area.sum() == pytest.approx(60 - 0.1 * (4 + 3 + 1), rel=1e-9)


def test_no_exit_is_an_error_unless_asked_for(tmp_path):
    """An exit on a layer named Door (not recognised): one line listing the drawing's layers, after the
    warning that lists what was ignored; --door-layers door makes it an exit, --no-exits meshes the plan with
    its entrance only; a WKT polygon without --exit likewise."""
    plan = office(tmp_path / "plan.dxf", exit_layer="Door")
    result = mesh(plan)
    one_line_error(result, "plan.dxf: exits = ['entrance']", "the plan has no exit", "no layer named exit*",
                   "Door, entrance, notes, walls", "--door-layers", "--no-exits")
    warning = [line for line in result.stderr.splitlines() if "ignored" in line]
    assert len(warning) == 1 and "layer 'Door': 1 LINE" in warning[0] and "layer 'notes': 1 TEXT" in warning[0]
    assert not (tmp_path / "plan.msh").exists()
    result = mesh(plan, "--door-layers", "door,entrance")
    assert result.exit_code == 0 and "door 1 m, entrance 1 m" in result.output, result.output
    result = mesh(plan, "--no-exits")
    assert result.exit_code == 0 and "exit" not in load_domain(tmp_path / "plan.msh").groups, result.output
    (tmp_path / "area.wkt").write_text("POLYGON ((0 0, 10 0, 10 6, 0 6, 0 0))\n")
    one_line_error(mesh(tmp_path / "area.wkt"), "area.wkt: exits = []", "--exit NAME=X0,Y0,X1,Y1")
    assert mesh(tmp_path / "area.wkt", "--no-exits").exit_code == 0


def test_a_clean_drawing_warns_of_nothing(tmp_path):
    result = mesh(office(tmp_path / "plan.dxf", extra=False))
    assert result.exit_code == 0 and result.stderr == "", result.stderr


def test_a_wkt_plan_with_an_internal_wall_in_centimetres(tmp_path):
    (tmp_path / "area.wkt").write_text("GEOMETRYCOLLECTION (POLYGON ((0 0, 1000 0, 1000 600, 0 600, 0 0)), "
                                       "LINESTRING (500 0, 500 400))\n")
    result = mesh(tmp_path / "area.wkt", "--units", "cm", "--exit", "exit=1000,50,1000,150")
    assert result.exit_code == 0, result.output
    domain = load_domain(tmp_path / "area.msh")
    assert domain.area.sum() == pytest.approx(60 - 0.1 * 4, rel=1e-9)
    assert domain.length[domain.groups["exit"]].sum() == pytest.approx(1.0, rel=1e-9)


@pytest.mark.parametrize("out, words", [("somedir", ["somedir: is a directory", "-o names the .msh file"]),
                                        ("out.vtk", ["out.vtk: femcrowd mesh writes gmsh .msh files only"])])
def test_bad_output_paths_are_one_line(tmp_path, out, words):
    (tmp_path / "somedir").mkdir()
    one_line_error(mesh(office(tmp_path / "plan.dxf", extra=False), "-o", tmp_path / out), *words)
    assert not (tmp_path / "out.vtk").exists() and not list(tmp_path.rglob("*.msh"))


def test_new_makes_the_entrance_a_source_and_needs_no_direction_without_exits(tmp_path):
    """femcrowd new on the office's mesh: exits ["exit"], the entrance a [[sources]] entry; on the mesh made
    with --no-exits: U = 0 and a note."""
    plan = office(tmp_path / "plan.dxf", extra=False)
    assert mesh(plan).exit_code == 0
    result = CliRunner().invoke(main, ["new", str(tmp_path / "case"), "--mesh", str(tmp_path / "plan.msh")])
    assert result.exit_code == 0, result.output
    case = load_case(tmp_path / "case")
    assert case["boundary"]["exits"] == ["exit"] and case["velocity"]["type"] == "exits"
    assert [(s["boundary"], s["flow"]) for s in case["sources"]] == [("entrance", 0.5)]
    assert mesh(plan, "--no-exits", "--door-layers", "entrance", "-o", tmp_path / "closed.msh").exit_code == 0
    result = CliRunner().invoke(main, ["new", str(tmp_path / "closed"), "--mesh", str(tmp_path / "closed.msh")])
    assert result.exit_code == 0 and "no exit" in result.output, result.output
    case = load_case(tmp_path / "closed")
    assert case["boundary"]["exits"] == [] and (case["velocity"]["ux"], case["velocity"]["uy"]) == ("0", "0")
    assert [s["boundary"] for s in case["sources"]] == ["entrance"]


@pytest.mark.parametrize("insunits, words", [(21, "$INSUNITS = 21: USSurveyFeet: ezdxf.units has no factor"),
                                             (8, "$INSUNITS = 8: Microinches"), (99, "$INSUNITS = 99: not a DXF unit")])
def test_units_without_a_conversion_are_refused_by_name(tmp_path, insunits, words):
    """A unit ezdxf cannot convert, or a code that is no unit, is not read as metres: one line naming it."""
    plan = office(tmp_path / "plan.dxf", 1.0, insunits)
    one_line_error(mesh(plan), "plan.dxf", words, "--units (mm, cm")
    assert mesh(plan, "--units", "m").exit_code == 0
    assert (tmp_path / "plan.msh").is_file()


def test_an_outline_on_another_layer_lists_the_layers(tmp_path):
    """Walls on A-WALL (a common CAD layer name): the error lists the drawing's layers and names --walls-layer,
    with which the plan meshes."""
    plan = office(tmp_path / "plan.dxf")
    doc = ezdxf.readfile(plan)
    doc.layers.new("A-WALL")
    for entity in doc.modelspace().query('*[layer=="walls"]'):
        entity.dxf.layer = "A-WALL"
    doc.saveas(plan)
    one_line_error(mesh(plan), "plan.dxf: no outline: the walls layer 'walls' holds no LINE",
                   "layers: A-WALL, entrance, exit, notes", "--walls-layer")
    assert mesh(plan, "--walls-layer", "A-WALL").exit_code == 0


def two_rooms(path, door_layer="doors_AB", swing=False, top=8000):
    """Two 10 x 8 m rooms drawn in millimetres, side by side: the outline a closed polyline on "walls", the
    partition at x = 10 m as two LINEs from y = 0 and up to y = `top` (mm) leaving a 1.2 m doorway (y in [3.4,
    4.6] m), a LINE across the doorway on `door_layer` (None: none), an exit of 1.2 m at x = 20 m; with `swing`,
    a door swing on "walls": the leaf from the hinge (10, 3.4) to (8.8, 3.4) and an ARC of radius 1.2 m around
    the hinge from the doorway's other end to the leaf."""
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    walls = {"layer": "walls"}
    msp.add_lwpolyline([(0, 0), (20000, 0), (20000, 8000), (0, 8000)], close=True, dxfattribs=walls)
    msp.add_line((10000, 0), (10000, 3400), dxfattribs=walls)
    msp.add_line((10000, 4600), (10000, top), dxfattribs=walls)
    if door_layer:
        msp.add_line((10000, 3400), (10000, 4600), dxfattribs={"layer": door_layer})
    msp.add_line((20000, 3400), (20000, 4600), dxfattribs={"layer": "exit"})
    if swing:
        msp.add_line((10000, 3400), (8800, 3400), dxfattribs=walls)
        msp.add_arc((10000, 3400), 1200, 90, 180, dxfattribs=walls)   # (10, 4.6) -> (8.8, 3.4) m
    doc.saveas(path)
    return path


def test_a_doors_layer_makes_an_interior_door_that_takes_a_capacity(tmp_path):
    """The two rooms in millimetres, the doorway's line on the layer doors_AB: a line group doors_ab of 1.2 m of
    interior edges on x = 10 (nothing else interior is named); a case with a capacity of 0.5 on it and the left
    room full runs with the total mass conserved (mass + evacuated), 0 <= rho <= 1, p >= 0, the door's flow at
    most 0.5 x 1.2 persons per second and at exactly that while the queue lasts; a counting line drawn on the door
    counts exactly the door's flow summed over the steps."""
    result = mesh(two_rooms(tmp_path / "plan.dxf"), "--size", "0.5")
    assert result.exit_code == 0 and result.stderr == "", result.output
    domain = load_domain(tmp_path / "plan.msh", ["exit"])
    door = domain.groups["doors_ab"]
    mid = domain.points[domain.mesh.facets[:, door]].mean(axis=0)
    assert np.all(domain.interior[door]) and np.allclose(mid[:, 0], 10.0)
    assert domain.length[door].sum() == pytest.approx(1.2, rel=1e-12)
    (tmp_path / "case.toml").write_text(
        '[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["exit"]\ncapacity = { doors_ab = 0.5 }\n'
        '[initial]\ndensity = "1.0 * (x < 9)"\n[time]\nend = 3.0\n'
        '[[measure.lines]]\nname = "ab"\nfrom = [10, 3.4]\nto = [10, 4.6]\n')
    run = Simulation(load_case(tmp_path)).run()
    h = run.history
    assert run.summary["status"] == "completed" and len(h["time"]) > 3
    mass0 = h["mass"][0]
    assert np.abs(h["mass"] + h["evacuated"] - mass0).max() <= 1e-10 * mass0
    assert h["min_density"].min() >= -1e-12 and h["max_density"].max() <= 1 + 1e-9 and h["min_pressure"].min() >= 0
    assert h["flow_doors_ab"].max() <= 0.5 * 1.2 * (1 + 1e-12)
    assert h["flow_doors_ab"][-1] == pytest.approx(0.6, rel=1e-12)
    passed = np.sum(h["flow_doors_ab"][1:] * np.diff(h["time"]))
    assert run.measurements["ab_count"][-1] == pytest.approx(passed, rel=1e-12) and 1.0 < passed <= 0.6 * 3.0


def test_a_door_swing_on_the_walls_layer_is_named_where_it_closes_the_doorway(tmp_path):
    """The doorway's swing (a leaf LINE and an ARC) drawn on "walls": one warning naming the ARC and its ends in
    metres, (10, 4.6) and (8.8, 3.4); with no other way between the rooms the plan is then refused (cut into 2
    parts); with a second doorway at the top of the partition it meshes, the warning still there. The rounded
    corner of an outline (an ARC in the closed loop) warns of nothing (test_a_clean_drawing_warns_of_nothing's
    office has none; `drawing` has one)."""
    def swing_warnings(result):
        return [line for line in result.stderr.splitlines() if "door swing" in line]

    closed = mesh(two_rooms(tmp_path / "closed.dxf", None, swing=True))
    one_line_error(closed, "closed.dxf", "cut the plan into 2 parts")
    meshed = mesh(two_rooms(tmp_path / "open.dxf", None, swing=True, top=7000))
    assert meshed.exit_code == 0, meshed.output
    for result, name in ((closed, "closed.dxf"), (meshed, "open.dxf")):
        (line,) = swing_warnings(result)
        assert name in line and "layer 'walls' ARC #" in line and "from (10, 4.6) to (8.8, 3.4) m" in line, line
    assert not swing_warnings(mesh(two_rooms(tmp_path / "plain.dxf", None, top=7000)))
    rounded = mesh(drawing(tmp_path / "rounded.dxf", "lines and an arc"))
    assert rounded.exit_code == 0 and not swing_warnings(rounded), rounded.output


@pytest.mark.parametrize("layer, options, group", [("doors", (), "doors"), ("door_AB", ("--doors-layer", "door"),
                                                                            "door_ab"),
                                                   ("doors", ("--door-layers", "exit,doors"), "doors")])
def test_interior_doors_are_named_after_their_layer(tmp_path, layer, options, group):
    """The exits' rule: the layer `doors` makes the group doors; with --doors-layer door, the layer door_AB makes
    door_ab (the name of issue 36), not an ignored layer; a layer that is also an exit prefix holds interior
    doors; the group is the 1.2 m of the doorway, all interior edges."""
    result = mesh(two_rooms(tmp_path / "plan.dxf", layer), *options)
    assert result.exit_code == 0 and result.stderr == "", result.output
    domain = load_domain(tmp_path / "plan.msh", ["exit"])
    assert set(domain.groups) == {"wall", "exit", group} and np.all(domain.interior[domain.groups[group]])
    assert domain.length[domain.groups[group]].sum() == pytest.approx(1.2, rel=1e-12)


def test_a_door_line_outside_the_plan_or_named_as_an_exit_is_refused(tmp_path):
    """A line on the doors layer along the outline (not inside), or a door named like an exit (given with --exit):
    one line naming the layer and the entity, no mesh."""
    plan = two_rooms(tmp_path / "plan.dxf")
    doc = ezdxf.readfile(plan)
    doc.modelspace().add_line((0, 1000), (0, 2000), dxfattribs={"layer": "doors_west"})
    doc.saveas(plan)
    one_line_error(mesh(plan), "plan.dxf: layer 'doors_west' LINE #", "the door must lie inside the domain")
    one_line_error(mesh(two_rooms(tmp_path / "named.dxf"), "--exit", "doors_ab=20000,1000,20000,2000"),
                   "layer 'doors_AB' LINE #", "other than wall, domain and the exits'")
    assert not list(tmp_path.glob("*.msh"))
