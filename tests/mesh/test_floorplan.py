"""Floor plans to gmsh meshes: areas, exit groups, bad input, shipped meshes."""


import os

import gmsh
import numpy as np
import pytest
import skfem
from click.testing import CliRunner

from femcrowd.cli import main
from femcrowd.errors import InputError
from femcrowd.mesh import read_mesh
from femcrowd.mesh.floorplan import build_mesh

from ..support import MESHES

ROOM = """
size = 0.5
[outer]
points = [[0, 0], [0, 6], [10, 6], [10, 0]]   # clockwise on purpose
[[exits]]
name = "exit"
from = [10, 2.5]
to = [10, 3.5]
size = 0.1
[[exits]]
name = "exit"
from = [0, 6]
to = [0, 5]
[[exits]]
name = "hatch"
from = [3, 2]
to = [2.5, 2]
[[holes]]
points = [[2, 2], [3, 2], [3, 3]]
"""
CIRCLE = '\n[[holes]]\ncircle = { center = [7, 3], radius = 0.5 }\n'


def write(tmp_path, text, name="plan.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def areas(m):
    x = m.p[:, m.t]
    return 0.5 * np.abs((x[0, 1] - x[0, 0]) * (x[1, 2] - x[1, 0]) - (x[0, 2] - x[0, 0]) * (x[1, 1] - x[1, 0]))


def lengths(m):
    """Total length of each named boundary group."""
    h = np.linalg.norm(m.p[:, m.facets[1]] - m.p[:, m.facets[0]], axis=0)
    return {name: h[f].sum() for name, f in m.boundaries.items()}


def non_delaunay(m):
    """Interior edges whose two opposite angles sum to more than pi (cot a + cot b < 0)."""
    x = m.p[:, m.t]
    cot = np.zeros(m.facets.shape[1])
    for k, o in enumerate([2, 0, 1]):  # skfem: facet t2f[k] is opposite vertex o
        u, v = x[:, (o + 1) % 3] - x[:, o], x[:, (o + 2) % 3] - x[:, o]
        cot += np.bincount(m.t2f[k], (u * v).sum(0) / np.abs(u[0] * v[1] - u[1] * v[0]), len(cot))
    return np.count_nonzero(cot[m.f2t[1] >= 0] < -1e-12)


def test_polygon_plan(tmp_path):
    out = build_mesh(write(tmp_path, ROOM))
    assert out == tmp_path / "plan.msh"
    assert out.read_text().startswith("$MeshFormat\n2.2")
    m = skfem.MeshTri.load(out)
    assert areas(m).sum() == pytest.approx(60 - 0.5, abs=1e-10)
    length = lengths(m)
    assert set(length) == {"exit", "hatch", "wall"}
    assert length["exit"] == pytest.approx(2, abs=1e-12)
    assert length["hatch"] == pytest.approx(0.5, abs=1e-12)
    assert length["wall"] == pytest.approx(32 - 2 + 2 + np.sqrt(2) - 0.5, abs=1e-12)
    exit_facets = m.facets[:, m.boundaries["exit"]]
    assert np.linalg.norm(np.diff(m.p[:, exit_facets], axis=1), axis=0).min() <= 0.1 + 1e-9
    assert non_delaunay(m) == 0
    assert lengths(m.refined(1)) == pytest.approx(length)


def test_circle_hole_and_options(tmp_path):
    out = build_mesh(write(tmp_path, ROOM + CIRCLE), out=tmp_path / "x.msh", refine_exits=0.05)
    assert out == tmp_path / "x.msh"
    m = skfem.MeshTri.load(out)
    # the circle becomes a polygon inscribed in it, with chords of about `size`
    wall = m.facets[:, m.boundaries["wall"]]
    a, b = np.swapaxes(m.p[:, wall] - np.array([7, 3])[:, None, None], 0, 1)  # the two ends
    ring = (np.abs(np.linalg.norm(a, axis=0) - 0.5) < 1e-9) & (np.abs(np.linalg.norm(b, axis=0) - 0.5) < 1e-9)
    n, hole = np.count_nonzero(ring), 0.5 * np.abs(a[0] * b[1] - a[1] * b[0])[ring].sum()
    assert areas(m).sum() == pytest.approx(60 - 0.5 - hole, abs=1e-10)
    assert 0.5 * n * np.sin(2 * np.pi / n) * 0.25 == pytest.approx(hole, abs=1e-12)
    assert n >= 2 * np.pi * 0.5 / 0.5
    hatch = m.facets[:, m.boundaries["hatch"]]
    assert np.linalg.norm(np.diff(m.p[:, hatch], axis=1), axis=0).max() <= 0.05 + 1e-9


BAD = {
    "syntax": ("size = = 1", None, "TOML syntax error"),
    "unknown": ("sise = 0.1\n[outer]\npoints = [[0,0],[1,0],[0,1]]", "sise", "did you mean 'size'"),
    "unknown_nested": ("[outer]\npoint = [[0,0],[1,0],[0,1]]", "outer.point", "did you mean 'points'"),
    "no_outer": ("size = 0.1", "outer", "missing"),
    "size": ("size = 0\n[outer]\npoints = [[0,0],[1,0],[0,1]]", "size", "positive"),
    "two_points": ("[outer]\npoints = [[0,0],[1,0]]", "outer.points", "at least 3 points"),
    "not_points": ("[outer]\npoints = [[0,0],[1,0],[1]]", "outer.points", "[x, y]"),
    "bowtie": ("[outer]\npoints = [[0,0],[1,1],[1,0],[0,1]]", "outer.points", "intersects itself"),
    "exit_off": ('[[exits]]\nname = "e"\nfrom = [5, 3]\nto = [5, 4]', "exits[0]", "must lie on one straight edge"),
    "exit_corner": ('[[exits]]\nname = "e"\nfrom = [9, 0]\nto = [10, 1]', "exits[0]", "must lie on one straight edge"),
    "exit_name": ('[[exits]]\nname = "wall"\nfrom = [10, 2]\nto = [10, 3]', "exits[0].name", "other than"),
    "exit_size": ('[[exits]]\nname = "e"\nfrom = [10, 2]\nto = [10, 3]\nsize = -1', "exits[0].size", "positive"),
    "exits_overlap": ('[[exits]]\nname = "e"\nfrom = [10, 2]\nto = [10, 3]\n'
                      '[[exits]]\nname = "f"\nfrom = [10, 2.5]\nto = [10, 4]', "exits[1]", "overlaps exits[0]"),
    "hole_outside": ("[[holes]]\ncircle = { center = [20, 3], radius = 0.5 }", "holes[0]", "strictly inside"),
    "hole_crosses": ("[[holes]]\ncircle = { center = [9.8, 3], radius = 0.5 }", "holes[0]", "strictly inside"),
    "hole_touches": ("[[holes]]\npoints = [[8,0],[9,1],[8,1]]", "holes[0]", "strictly inside"),
    "holes_overlap": ("[[holes]]\ncircle = { center = [5, 3], radius = 0.5 }\n"
                      "[[holes]]\npoints = [[4,2],[4.8,2],[4.8,3]]", "holes[1]", "overlaps holes[0]"),
    "hole_in_hole": ("[[holes]]\npoints = [[4,2],[6,2],[6,4],[4,4]]\n"
                     "[[holes]]\ncircle = { center = [5, 3], radius = 0.5 }", "holes[1]", "overlaps holes[0]"),
    "holes_table": ("[holes]\npoints = [[1,1],[2,1],[2,2]]", "holes", "array of tables"),
    "hole_kind": ("[[holes]]\ncircle = { center = [5, 3], radius = 0.5 }\npoints = [[1,1],[2,1],[2,2]]",
                  "holes[0]", "exactly one"),
    "radius": ("[[holes]]\ncircle = { center = [5, 3], radius = 0 }", "holes[0].circle.radius", "positive"),
    "door_outside": ('[[doors]]\nname = "d"\nfrom = [5, 0]\nto = [5, 8]', "doors[0]", "must lie inside the domain"),
    "door_through_hole": ('[[holes]]\ncircle = { center = [5, 3], radius = 0.5 }\n'
                          '[[doors]]\nname = "d"\nfrom = [5, 0]\nto = [5, 6]', "doors[0]", "must lie inside"),
    "door_name": ('[[doors]]\nname = "wall"\nfrom = [5, 0]\nto = [5, 6]', "doors[0].name", "other than"),
    "door_key": ('[[doors]]\nname = "d"\nfrom = [5, 0]\nto = [5, 6]\nsize = 0.1', "doors[0].size", "unknown key"),
    "tiny": ("[outer]\npoints = [[0, 0], [0.5, 0], [0, 0.5]]", "units", "0.5 m x 0.5 m, not the size of a building"),
    "huge": ("[outer]\npoints = [[0, 0], [2e4, 0], [0, 10]]", "units", "2e+04 m x 10 m, not the size of a building"),
    "too_many": ("size = 0.01\n[outer]\npoints = [[0, 0], [1e3, 0], [1e3, 1e3], [0, 1e3]]", "units",
                 "it would take about 2e+10 triangles"),
    "wall_outside": ("[[walls]]\npoints = [[5, 0], [5, 8]]", "walls[0]", "must lie inside the outer boundary"),
    "wall_point": ("[[walls]]\npoints = [[5, 0]]", "walls[0].points", "at least 2 points"),
    "wall_repeated": ("[[walls]]\npoints = [[5, 0], [5, 0], [5, 3]]", "walls[0].points", "repeated"),
    "wall_thickness": ("[[walls]]\npoints = [[5, 0], [5, 3]]\nthickness = 0", "walls[0].thickness", "positive"),
    "wall_key": ("[[walls]]\npoints = [[5, 0], [5, 3]]\nwidth = 0.2", "walls[0].width", "unknown key"),
    "walls_close": ("[[walls]]\npoints = [[5, 0], [5, 6]]", "walls", "cut the plan into 2 parts (29.7, 29.7 m^2)"),
    "wall_circle": ("[[holes]]\ncircle = { center = [5, 3], radius = 0.5 }\n[[walls]]\npoints = [[5, 0], [5, 2.6]]",
                    "walls[0]", "touches a circle hole"),
    "no_exit": ("", "exits", "the plan has no exit"),
    "entrance_only": ('[[exits]]\nname = "entrance"\nfrom = [0, 2]\nto = [0, 3]', "exits", "has no exit"),
}


def test_an_interior_door_is_a_line_group_of_interior_edges(tmp_path):
    """A [[doors]] line across the room, its ends on the walls: a group of interior edges of its length, which a
    uniform refinement keeps; the walls it ends on stay one group."""
    path = build_mesh(write(tmp_path, ROOM + '[[doors]]\nname = "door"\nfrom = [6, 0]\nto = [6, 6]\n'))
    m = read_mesh(path, "case.toml")
    facets = m.boundaries["door"]
    assert np.all(m.f2t[1, facets] >= 0) and lengths(m)["door"] == pytest.approx(6.0, rel=1e-12)
    assert lengths(m.refined(1))["door"] == pytest.approx(6.0, rel=1e-12)
    plain = read_mesh(build_mesh(write(tmp_path, ROOM, "plain.toml")), "case.toml")
    assert lengths(m)["wall"] == pytest.approx(lengths(plain)["wall"], rel=1e-12)


def test_internal_walls_are_cut_out_with_their_thickness(tmp_path):
    """Two [[walls]] at x = 6 from the bottom and top walls, 0.2 m thick, a 2 m doorway between their free ends:
    the floor loses 2 x 2 x 0.2 m^2, the walls gain their sides and square ends (the notches in the outline
    are the strips' width), the exits are unchanged and the floor is one piece."""
    walls = ('[[walls]]\npoints = [[6, 0], [6, 2]]\nthickness = 0.2\n'
             '[[walls]]\npoints = [[6, 4], [6, 6]]\nthickness = 0.2\n')
    m = read_mesh(build_mesh(write(tmp_path, ROOM + walls)), "case.toml")
    plain = read_mesh(build_mesh(write(tmp_path, ROOM, "plain.toml")), "case.toml")
    assert areas(m).sum() == pytest.approx(60 - 0.5 - 0.8, rel=1e-12)
    assert lengths(m)["wall"] == pytest.approx(lengths(plain)["wall"] + 2 * (2 + 2), rel=1e-12)
    assert lengths(m)["exit"] == pytest.approx(2, rel=1e-12) and lengths(m)["hatch"] == pytest.approx(0.5)
    centroids = m.p[:, m.t].mean(axis=1)
    assert not ((np.abs(centroids[0] - 6) < 0.1) & ((centroids[1] < 2) | (centroids[1] > 4))).any()
    assert non_delaunay(m) == 0


@pytest.mark.parametrize("case", BAD)
def test_bad_geometry(tmp_path, case):
    text, key, message = BAD[case]
    if "[outer]" not in text and case not in ("syntax", "no_outer"):
        text = "[outer]\npoints = [[0,0],[10,0],[10,6],[0,6]]\n" + text
    path = write(tmp_path, text)
    with pytest.raises(InputError) as e:
        build_mesh(path, require_exits=case in ("no_exit", "entrance_only"))
    assert str(e.value).startswith(f"{path}: {key} =" if key else f"{path}:")
    assert message in str(e.value)
    assert not path.with_suffix(".msh").exists()


SHIPPED = {
    "room_one_door": {"exit": 1, "wall": 31},
    "room_obstacles": {"exit": 1, "wall": 31 + 2 * np.pi * 1.6},
    "two_exits": {"exit_wide": 2, "exit_narrow": 1, "wall": 61},
    "corridor": {"wall": 9},
    "square": {"wall": 8},
    "channel_exit": {"exit": 1, "wall": 5},
    "square_exits": {"exit": 8},
}


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_meshes(name):
    m = skfem.MeshTri.load(MESHES / f"{name}.msh")
    assert lengths(m) == pytest.approx(SHIPPED[name], rel=1e-2 if name == "room_obstacles" else 1e-12)
    assert lengths(m.refined(1)) == pytest.approx(lengths(m))
    assert non_delaunay(m) == 0
    # no obtuse triangles (except a few next to the obstacles): refinement keeps Delaunay
    assert non_delaunay(m.refined(1)) == 0 or name == "room_obstacles"


def test_units_and_wall_thickness_options_are_for_cad_plans(tmp_path):
    """A TOML plan is in metres and its walls carry their thickness: --units, --wall-thickness are refused."""
    path = write(tmp_path, ROOM)
    for option, value in (("units", "mm"), ("wall_thickness", 0.2)):
        with pytest.raises(InputError, match=f"plan.toml: --{option.replace('_', '-')} = .*for DXF and WKT plans"):
            build_mesh(path, cad={option: value})
    assert not path.with_suffix(".msh").exists()


def cut_short(monkeypatch):
    """gmsh.write as on a full disk: part of the file written, no error raised (gmsh's C stdio says nothing)."""
    write = gmsh.write

    def half(name):
        write(name)
        size = os.path.getsize(name)
        with open(name, "r+b") as f:
            f.truncate(size // 2)

    monkeypatch.setattr(gmsh, "write", half)


def test_a_mesh_cut_short_leaves_the_previous_mesh(tmp_path, monkeypatch):
    """A full disk under `femcrowd mesh` (gmsh writes half the file and raises nothing): one line naming the
    .msh, exit 2, the mesh there before byte for byte, no temporary file; before, the partial file was renamed
    onto it and the next run said "list index out of range"."""
    out = tmp_path / "room.msh"
    build_mesh(write(tmp_path, ROOM), out)
    before = out.read_bytes()
    cut_short(monkeypatch)
    result = CliRunner().invoke(main, ["mesh", str(write(tmp_path, ROOM + CIRCLE, "other.toml")), "-o", str(out)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(out) in lines[0] and "incomplete" in lines[0], result.stderr
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.toml", "plan.toml", "room.msh"]


def test_mesh_writes_no_file_through_a_link(tmp_path):
    """-o a link (to a file of someone else's, or dangling): refused with one line, the target untouched."""
    target, out = tmp_path / "target.msh", tmp_path / "room.msh"
    target.write_text("not femcrowd's\n")
    out.symlink_to(target)
    result = CliRunner().invoke(main, ["mesh", str(write(tmp_path, ROOM)), "-o", str(out)])
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1 and str(out) in result.stderr and "symbolic link" in result.stderr
    assert target.read_text() == "not femcrowd's\n" and out.is_symlink()
