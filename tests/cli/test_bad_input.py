"""Malformed cases and meshes through the real CLI: one line on stderr naming file, key and value,
exit code 2, no traceback, and a pre-existing output directory left exactly as it was."""

import json
import os
import subprocess
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from femcrowd.case import load_case
from femcrowd.cli import main
from femcrowd.driver.output import MARKER

from ..support import FEMCROWD


def msh(nodes, elements, names=()):
    """A gmsh 2.2 ASCII mesh: nodes [(x, y, z)], elements [(gmsh type, physical tag, node numbers)]."""
    text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
    if names:
        text += f"$PhysicalNames\n{len(names)}\n" + "".join(f'{d} {t} "{n}"\n' for d, t, n in names)
        text += "$EndPhysicalNames\n"
    text += f"$Nodes\n{len(nodes)}\n" + "".join(f"{i + 1} {x} {y} {z}\n" for i, (x, y, z) in enumerate(nodes))
    text += f"$EndNodes\n$Elements\n{len(elements)}\n"
    text += "".join(f"{i + 1} {kind} 2 {tag} {tag} {' '.join(map(str, v))}\n"
                    for i, (kind, tag, v) in enumerate(elements))
    return text + "$EndElements\n"


LINE, TRIANGLE, QUAD, TETRA = 1, 2, 3, 4
NAMES = [(1, 1, "wall"), (1, 2, "exit"), (1, 3, "door"), (2, 10, "domain")]


def grid(n=4, z=lambda x, y: 0.0, quads=False):
    """Unit square, n x n squares cut into triangles; side x = 0 is "exit", the rest "wall";
    "door" tags the interior vertical edges at x = 1/2 (not a boundary group)."""
    number = lambda i, j: j * (n + 1) + i + 1  # noqa: E731
    nodes = [(i / n, j / n, z(i / n, j / n)) for j in range(n + 1) for i in range(n + 1)]
    cells = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = number(i, j), number(i + 1, j), number(i + 1, j + 1), number(i, j + 1)
            cells += [(QUAD, 10, (a, b, c, d))] if quads else [(TRIANGLE, 10, (a, b, c)), (TRIANGLE, 10, (a, c, d))]
    lines = []
    for k in range(n):
        lines += [(LINE, 2, (number(0, k), number(0, k + 1))), (LINE, 1, (number(n, k), number(n, k + 1))),
                  (LINE, 1, (number(k, 0), number(k + 1, 0))), (LINE, 1, (number(k, n), number(k + 1, n))),
                  (LINE, 3, (number(n // 2, k), number(n // 2, k + 1)))]
    return nodes, lines + cells


GOOD_MESH = msh(*grid(), NAMES)
BASE = """title = "tiny room"

[mesh]
file = "mesh.msh"

[boundary]
exits = ["exit"]

[velocity]
type = "exits"

[initial]
density = 0.5

[time]
end = 0.1

[output]
every = 0.1
"""


def edit(old, new):
    assert old in BASE, old
    return BASE.replace(old, new)


def tet_mesh():
    nodes = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    return msh(nodes, [(TETRA, 10, (1, 2, 3, 4))], [(3, 10, "domain")])


def nan_mesh():
    nodes, elements = grid()
    nodes[6] = (float("nan"), nodes[6][1], 0.0)
    return msh(nodes, elements, NAMES)


def degenerate_mesh():
    nodes, elements = grid()
    return msh(nodes, elements + [(TRIANGLE, 10, (1, 2, 3))], NAMES)  # three nodes on y = 0


#: id -> (case.toml text, mesh text or bytes, --set overrides, key, value, words of the message)
BAD = {
    "missing mesh file": (edit('"mesh.msh"', '"nowhere.msh"'), GOOD_MESH, (), "mesh.file", "nowhere.msh", "not found"),
    "unknown exit group": (edit('["exit"]', '["exti"]'), GOOD_MESH, (), "boundary.exits", "'exti'",
                           "did you mean 'exit'"),
    "exit is a surface group": (edit('["exit"]', '["domain"]'), GOOD_MESH, (), "boundary.exits", "'domain'",
                                "no boundary group"),
    "exit made of interior edges": (edit('["exit"]', '["door"]'), GOOD_MESH, (), "boundary.exits", "'door'",
                                    "contains interior edges"),
    "unknown key": (edit("end = 0.1", "ende = 0.1"), GOOD_MESH, (), "time.ende", "0.1", "did you mean 'time.end'"),
    "unknown section": (edit("[time]", "[tyme]"), GOOD_MESH, (), "tyme", "", "did you mean 'time'"),
    "density above rho_max": (edit("density = 0.5", "density = 1.5"), GOOD_MESH, (), "initial.density", "1.5",
                              "outside [0, rho_max = 1]"),
    "negative density": (edit("density = 0.5", 'density = "0.5 - x"'), GOOD_MESH, (), "initial.density",
                         "0.5 - x", "outside"),
    "region density out of range": (BASE + "\n[initial.regions]\ndomain = 2.0\n", GOOD_MESH, (),
                                    "initial.regions.domain", "2.0", "outside"),
    "non-finite density": (edit("density = 0.5", 'density = "log(x - 5)"'), GOOD_MESH, (), "initial.density",
                           "log(x - 5)", "gives nan, not a finite number at 512 of 512 points"),
    "non-finite velocity": (edit('type = "exits"', 'type = "field"\nux = "1 / (x - x)"'), GOOD_MESH, (),
                            "velocity.ux", "1 / (x - x)", "gives inf, not a finite number at 88 of 88 points"),
    "attribute access": (edit("density = 0.5", 'density = "x.real"'), GOOD_MESH, (), "initial.density", "x.real",
                         "not allowed"),
    "import": (edit("density = 0.5", "density = \"__import__('os').system('echo owned')\""), GOOD_MESH, (),
               "initial.density", "__import__", "not allowed"),
    "dunder class": (edit("density = 0.5", 'density = "().__class__"'), GOOD_MESH, (), "initial.density",
                     "__class__", "not allowed"),
    "lambda": (edit("density = 0.5", 'density = "(lambda: 1)()"'), GOOD_MESH, (), "initial.density", "lambda",
               "not allowed"),
    "subscript": (edit("density = 0.5", 'density = "x[0]"'), GOOD_MESH, (), "initial.density", "x[0]", "not allowed"),
    "unknown name": (edit("density = 0.5", 'density = "z + 1"'), GOOD_MESH, (), "initial.density", "z + 1",
                     "unknown name 'z'"),
    "TOML syntax error": (edit("[time]", "[time"), GOOD_MESH, (), None, None, "TOML syntax error"),
    "end is a string": (edit("end = 0.1", 'end = "ten"'), GOOD_MESH, (), "time.end", "'ten'", "expected a number"),
    "exits is a string": (edit('["exit"]', '"exit"'), GOOD_MESH, (), "boundary.exits", "'exit'",
                          "expected a list of strings"),
    "refine is a float": (edit("[mesh]", "[mesh]\nrefine = 1.5"), GOOD_MESH, (), "mesh.refine", "1.5",
                          "expected an integer"),
    "negative end time": (edit("end = 0.1", "end = -1"), GOOD_MESH, (), "time.end", "-1", "must be in (0, inf)"),
    "infinite end time": (edit("end = 0.1", "end = inf"), GOOD_MESH, (), "time.end", "inf", "expected a finite"),
    "empty_fraction = 1": (BASE, GOOD_MESH, ("time.empty_fraction=1",), "time.empty_fraction", "1",
                           "must be in (0, 0.1]"),
    "arrays nested 600 deep": (BASE + "\n[convergence]\nmeshes = " + "[" * 600 + "]" * 600 + "\n", GOOD_MESH, (),
                               None, None, "nested too deeply"),
    "mesh file is a directory": (edit('"mesh.msh"', '"."'), GOOD_MESH, (), "mesh.file", "/case'",
                                 "is a directory, not a regular file"),
    "mesh file is a device": (edit('"mesh.msh"', '"/dev/zero"'), GOOD_MESH, (), "mesh.file", "/dev/zero",
                              "is a character device, not a regular file"),
    "route with a field velocity": (edit('type = "exits"', 'type = "field"\nux = 1.0\nroute = "congestion"'),
                                    GOOD_MESH, (), "velocity.route", "congestion", "no population has velocity "
                                    "type 'exits'"),
    "cfl = 0": (BASE, GOOD_MESH, ("time.cfl=0",), "time.cfl", "0", "must be in (0, 1]"),
    "cfl > 1": (BASE, GOOD_MESH, ("time.cfl=1.5",), "time.cfl", "1.5", "must be in (0, 1]"),
    "dt above the CFL limit": (BASE, GOOD_MESH, ("time.dt=10",), "time.dt", "10", "CFL limit"),
    "unknown output field": (edit("every = 0.1", 'every = 0.1\nfields = ["dens"]'), GOOD_MESH, (), "output.fields",
                             "dens", "unknown field"),
    "rho_max = 0": (BASE + "\n[model]\nrho_max = 0\n", GOOD_MESH, (), "model.rho_max", "0", "must be in (0"),
    "exits velocity without exits": (edit('["exit"]', "[]"), GOOD_MESH, (), "velocity.type", "exits",
                                     "needs at least one exit"),
    "exit speed depends on t": (edit('type = "exits"', 'type = "exits"\nspeed = "1 + t"'), GOOD_MESH, (),
                                "velocity.speed", "1 + t", "must not depend on t"),
    "negative exit speed": (edit('type = "exits"', 'type = "exits"\nspeed = "1 - 2 * x"'), GOOD_MESH, (),
                            "velocity.speed", "1 - 2 * x", "walk away from the exits"),
    "--set without =": (BASE, GOOD_MESH, ("time.end",), "time.end", None, "expected --set section.key=value"),
    "case file not UTF-8": (b"title = '\xff\xfe'\n", GOOD_MESH, (), None, None, "not a text file"),
    "3D mesh": (BASE, tet_mesh(), (), "mesh.file", "mesh.msh", "3D mesh"),
    "3D surface mesh": (BASE, msh(*grid(z=lambda x, y: x * y), NAMES), (), "mesh.file", "mesh.msh", "not planar"),
    "quads only": (BASE, msh(*grid(quads=True), NAMES), (), "mesh.file", "mesh.msh", "no triangles (only line, quad"),
    "no boundary names": (BASE, msh(*grid()), (), "boundary.exits", "'exit'", "groups: none"),
    "empty mesh": (BASE, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", (), "mesh.file", "mesh.msh", "no triangles"),
    "NaN in the mesh": (BASE, nan_mesh(), (), "mesh.file", "mesh.msh", "non-finite node coordinates"),
    "mesh without triangles": (BASE, msh(grid()[0], [e for e in grid()[1] if e[0] == LINE], NAMES), (),
                               "mesh.file", "mesh.msh", "no triangles (only line cells)"),
    "not a mesh file": (BASE, "this is not a mesh\n", (), "mesh.file", "mesh.msh", "cannot read a gmsh .msh"),
    "zero-area triangle": (BASE, degenerate_mesh(), (), "mesh.file", "mesh.msh", "degenerate"),
    "schedule not pairs": (BASE + "\n[boundary.open]\nexit = [1, 2]\n", GOOD_MESH, (), "boundary.open.exit",
                           "[1, 2]", "list of [from, to] pairs"),
    "schedule from > to": (BASE + "\n[boundary.open]\nexit = [[3, 2]]\n", GOOD_MESH, (), "boundary.open.exit",
                           "[[3, 2]]", "0 <= from < to"),
    "schedule of a wall": (BASE + "\n[boundary.open]\nwall = [[0, 1]]\n", GOOD_MESH, (), "boundary.open.wall",
                           "[[0.0, 1.0]]", "is not an exit"),
    "source on an exit": (BASE + '\n[[sources]]\nboundary = "exit"\nflow = 1.0\n', GOOD_MESH, (),
                          "sources[0].boundary", "exit", "is an exit"),
    "source on an unknown group": (BASE + '\n[[sources]]\nboundary = "entrance"\nflow = 1.0\n', GOOD_MESH, (),
                                   "sources[0].boundary", "entrance", "no boundary group"),
    "negative flow": (BASE + '\n[[sources]]\nboundary = "wall"\nflow = -1.0\n', GOOD_MESH, (),
                      "sources[0].flow", "-1.0", "must be in [0"),
    "source without flow": (BASE + '\n[[sources]]\nboundary = "wall"\n', GOOD_MESH, (),
                            "sources[0].flow", None, "missing required key"),
    "flow table of unsorted times": (BASE + '\n[[sources]]\nboundary = "wall"\nflow = [[0, 1], [2, 1], [1, 0]]\n',
                                     GOOD_MESH, (), "sources[0].flow", "[[0, 1], [2, 1], [1, 0]]",
                                     "the times must not decrease: 1 after 2"),
    "rate table with a negative rate": (BASE + '\n[[sources]]\nboundary = "wall"\nrate = [[0, 1], [1, -2]]\n',
                                        GOOD_MESH, (), "sources[0].rate", "[[0, 1], [1, -2]]",
                                        "a flow is >= 0, not -2"),
    "flow expression that does not parse": (BASE + '\n[[sources]]\nboundary = "wall"\nflow = "1 +* t"\n',
                                            GOOD_MESH, (), "sources[0].flow", "1 +* t", "syntax error"),
    "flow expression in x": (BASE + '\n[[sources]]\nboundary = "wall"\nflow = "x * t"\n', GOOD_MESH, (),
                             "sources[0].flow", "x * t", "unknown name 'x' (variables: t;"),
    "flow expression negative in [start, end]": (BASE + '\n[[sources]]\nboundary = "wall"\nflow = "0.05 - t"\n',
                                                 GOOD_MESH, (), "sources[0].flow", "0.05 - t",
                                                 "a flow is >= 0, but this gives -0.0001 at t = 0.0501"),
    "flow and rate": (BASE + '\n[[sources]]\nboundary = "wall"\nflow = 1.0\nrate = 2.0\n', GOOD_MESH, (),
                      "sources[0]", "{'flow': 1.0, 'rate': 2.0}", "give only one of flow"),
    "negative people": (BASE + '\n[[sources]]\nboundary = "wall"\npeople = -200\n', GOOD_MESH, (),
                        "sources[0].people", "-200", "must be in (0"),
    "people that do not fit": (edit("density = 0.5", "density = 0.5\npeople = 1.5"), GOOD_MESH, (), "initial.people",
                               "1.5", "persons do not fit under rho_max = 1 in the shape of the initial density"),
    "initial people with populations": (edit("density = 0.5", "people = 10\n[populations.a]\ndensity = 0.5"),
                                        GOOD_MESH, (), "initial.people", "10", "each population has its own"),
    "line of zero length": (BASE + '\n[[measure.lines]]\nname = "a"\nfrom = [0.5, 0.5]\nto = [0.5, 0.5]\n',
                            GOOD_MESH, (), "measure.lines[0].to", "[0.5, 0.5]", "zero length"),
    "line outside the domain": (BASE + '\n[[measure.lines]]\nname = "a"\nfrom = [0.5, 0.5]\nto = [2, 2]\n',
                                GOOD_MESH, (), "measure.lines[0]", "[0.5, 0.5] -> [2.0, 2.0]", "leaves the domain"),
    "self-intersecting area": (BASE + '\n[[measure.areas]]\nname = "a"\n'
                               'polygon = [[0.1, 0.1], [0.9, 0.9], [0.9, 0.1], [0.1, 0.9]]\n', GOOD_MESH, (),
                               "measure.areas[0].polygon", "[[0.1, 0.1]", "Self-intersection"),
    "area outside the domain": (BASE + '\n[[measure.areas]]\nname = "a"\npolygon = [[2, 2], [3, 2], [3, 3]]\n',
                                GOOD_MESH, (), "measure.areas[0].polygon", "[[2.0, 2.0]", "outside the domain"),
}



def with_expression(key, source):
    """BASE with `source` as the expression of `key`: initial.density, velocity.speed, velocity.speed_law,
    velocity.ux (type "field") or populations.a.density (one population)."""
    if key == "initial.density":
        return edit("density = 0.5", f'density = "{source}"')
    if key == "populations.a.density":
        return edit("[initial]\ndensity = 0.5\n", f'[populations.a]\ndensity = "{source}"\n')
    if key == "velocity.ux":
        return edit('type = "exits"', f'type = "field"\nux = "{source}"')
    return edit('type = "exits"', f'type = "exits"\n{key.split(".")[1]} = "{source}"')


#: id -> (key, expression, words of the message): refused at once by `femcrowd run` and `femcrowd info`
#: (10**10**10, which never ended, is tested in real processes below)
BAD_EXPRESSIONS = {
    "1/0": ("initial.density", "1/0", "gives inf, not a finite number (a division by zero or an overflow)"),
    "1%0": ("initial.density", "1%0", "gives nan, not a finite number (0/0, a % 0"),
    "10.0**1000": ("velocity.speed", "10.0**1000", "gives inf, not a finite number"),
    "(-1)**0.5": ("velocity.ux", "(-1)**0.5", "gives nan, not a finite number"),
    "2**2**2**2**2": ("populations.a.density", "2**2**2**2**2", "gives inf, not a finite number"),
    "1/x at nodes": ("velocity.ux", "1/x",
                     "gives inf, not a finite number at 4 of 88 points, first at x = 0, y = 0.125"),
    "speed law 1%0": ("velocity.speed_law", "1 - 1 % 0", "f(rho) gives nan, not a finite number"),
    "speed law with a pole": ("velocity.speed_law", "1 - 0.1 / (rho - 0.5)",
                              "f(rho) gives -inf, not a finite number at 1 of 4097 points, first at rho = 0.5"),
    "too many arguments": ("initial.density", "sqrt(x, y)", "sqrt() takes 1 argument, not 2"),
    "too few arguments": ("velocity.speed_law", "where(rho < 1)", "where() takes 3 arguments, not 1"),
    "unknown function": ("velocity.speed", "gamma(x)", "function 'gamma' is not allowed"),
    "unknown name": ("populations.a.density", "z + 1", "unknown name 'z'"),
    "integer beyond floats": ("initial.density", "1" * 400, "a number is beyond the range of floats"),
    "200,000-term sum": ("initial.density", "+".join(["x"] * 200000),
                         "is 399999 characters long: an expression may have at most 10000"),
    "50,000 nested not": ("velocity.speed", "not " * 50000 + "x", "is 200001 characters long"),
    "nested too deeply": ("velocity.ux", "-" * 5000 + "x", "is nested too deeply"),
    "201-term sum": ("initial.density", "+".join(["x"] * 201), "is nested too deeply"),
}

def write_case(tmp_path, toml, mesh):
    case = tmp_path / "case"
    case.mkdir()
    for name, text in (("case.toml", toml), ("mesh.msh", mesh)):
        (case / name).write_bytes(text if isinstance(text, bytes) else text.encode())
    return case


def previous_run(tmp_path):
    """An output directory holding an earlier femcrowd run; returns a snapshot function."""
    out = tmp_path / "out"
    out.mkdir()
    for name, text in ((MARKER, "written by femcrowd\n"), ("summary.json", '{"status": "completed"}\n'),
                       ("history.csv", "time,mass\n0.1,1.0\n"), ("solution_00000.vtu", "<VTKFile/>\n")):
        (out / name).write_text(text)
    return out


def snapshot(path):
    path = Path(path)
    files = [path] if path.is_file() else sorted(path.rglob("*"))
    return {str(f): (f.read_bytes(), f.stat().st_mtime_ns) for f in files}


def assert_refused(stderr, case_file, key, value, words):
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    line = lines[0]
    assert line.startswith("femcrowd: error: "), line
    assert "Traceback" not in stderr
    assert str(case_file) in line, line
    for part in (key, value, words):
        if part:
            assert part in line, f"{part!r} not in {line!r}"


def test_the_base_case_runs(tmp_path):
    """The malformed cases below differ from this one by their single defect."""
    case = write_case(tmp_path, BASE, GOOD_MESH)
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "summary.json").is_file()


def assert_run_refused(tmp_path, toml, mesh, overrides, key, value, words):
    """`femcrowd run` of this case with these --set overrides: exit code 2, nothing on stdout, the one line
    naming file, key and value on stderr, and a previous run's output directory left as it was."""
    case = write_case(tmp_path, toml, mesh)
    out = previous_run(tmp_path)
    before = snapshot(out)
    args = ["run", str(case), "--out", str(out), "-q"] + [a for o in overrides for a in ("--set", o)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert_refused(result.stderr, case / "case.toml", key, value, words)
    assert snapshot(out) == before


@pytest.mark.parametrize("name", list(BAD))
def test_bad_input_is_refused_cleanly(tmp_path, name):
    assert_run_refused(tmp_path, *BAD[name])


def test_a_fifo_as_mesh_file_is_named(tmp_path):
    """A named pipe would block the reader: refused as what it is, not as a missing file."""
    os.mkfifo(tmp_path / "pipe.msh")
    assert_run_refused(tmp_path, edit('"mesh.msh"', '"../pipe.msh"'), GOOD_MESH, (), "mesh.file", "pipe.msh",
                       "is a fifo (named pipe), not a regular file")


def test_arrays_nested_600_deep_in_a_set_are_one_line(tmp_path):
    case = write_case(tmp_path, BASE, GOOD_MESH)
    deep = "[" * 600 + "]" * 600
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(tmp_path / "out"), "-q",
                                       "--set", f"convergence.meshes={deep}"])
    assert result.exit_code == 2 and result.stdout == "" and "Traceback" not in result.stderr
    [line] = result.stderr.splitlines()
    assert line.startswith(f"femcrowd: error: {case / 'case.toml'}: convergence.meshes = '[[[")
    assert "nested too deeply" in line
    assert not (tmp_path / "out").exists()


def test_a_byte_order_mark_is_skipped(tmp_path):
    """Editors on Windows write UTF-8 with a BOM: the case loads as it does without."""
    plain = load_case(write_case(tmp_path, BASE, GOOD_MESH))
    (tmp_path / "case" / "case.toml").write_bytes(b"\xef\xbb\xbf" + BASE.encode())
    assert load_case(tmp_path / "case").config == plain.config


def test_output_dir_that_is_a_file(tmp_path):
    case = write_case(tmp_path, BASE, GOOD_MESH)
    out = tmp_path / "results"
    out.write_text("my notes\n")
    before = snapshot(out)
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(out), "-q"])
    assert result.exit_code == 2
    assert_refused(result.stderr, case / "case.toml", "output.dir", str(out), "not a directory")
    assert snapshot(out) == before


def test_foreign_output_dir_needs_force(tmp_path):
    """A directory femcrowd did not write is refused, untouched; --force writes into it (and keeps
    the foreign file); it stays foreign, so the next run needs --force again."""
    case = write_case(tmp_path, BASE, GOOD_MESH)
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me\n")
    before = snapshot(out)
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(out), "-q"])
    assert result.exit_code == 2
    assert_refused(result.stderr, case / "case.toml", "output.dir", str(out), "--force")
    assert snapshot(out) == before
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(out), "-q", "--force"])
    assert result.exit_code == 0, result.output
    assert (out / "notes.txt").read_text() == "keep me\n" and (out / "summary.json").is_file()
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(out), "-q"])
    assert result.exit_code == 2
    assert (out / "notes.txt").read_text() == "keep me\n"


SUBPROCESS = ["missing mesh file", "3D mesh", "import", "TOML syntax error", "not a mesh file", "cfl > 1"]


def test_no_traceback_reaches_the_terminal(tmp_path):
    """The installed `femcrowd run` (a real process): one line, exit code 2, for a few of the cases."""
    procs = {}
    for name in SUBPROCESS:
        toml, mesh, overrides, *_ = BAD[name]
        here = tmp_path / name.replace(" ", "_")
        here.mkdir()
        case = write_case(here, toml, mesh)
        args = [str(FEMCROWD), "run", str(case), "--out", str(here / "out"), "-q"]
        procs[name] = (here, subprocess.Popen(args + [a for o in overrides for a in ("--set", o)],
                                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    for name, (here, proc) in procs.items():
        stdout, stderr = proc.communicate(timeout=120)
        _, _, _, key, value, words = BAD[name]
        assert proc.returncode == 2, (name, stderr)
        assert stdout == "", (name, stdout)
        assert_refused(stderr, here / "case" / "case.toml", key, value, words)
        assert not (here / "out").exists()


@pytest.mark.parametrize("command", ["run", "info"])
@pytest.mark.parametrize("name", list(BAD_EXPRESSIONS))
def test_bad_expression_is_refused_at_once(tmp_path, name, command):
    """`femcrowd run` (a previous run left as it was) and `femcrowd info`: exit code 2, one line naming file, key
    and expression (its start when long); never a traceback or a MemoryError (a hang: the processes of
    test_big_powers_are_refused_at_once)."""
    key, source, words = BAD_EXPRESSIONS[name]
    if command == "run":
        assert_run_refused(tmp_path, with_expression(key, source), GOOD_MESH, (), key, source[:150], words)
    else:
        case = write_case(tmp_path, with_expression(key, source), GOOD_MESH)
        result = CliRunner().invoke(main, ["info", str(case)])
        assert result.exit_code == 2, result.output
        assert result.stdout == ""
        assert_refused(result.stderr, case / "case.toml", key, source[:150], words)


def test_big_powers_are_refused_at_once(tmp_path):
    """10**10**10 used to compute a ten-billion-digit integer (100 % CPU, growing memory, Ctrl-C ignored, for
    ever) in `femcrowd run` and `femcrowd info`. The installed command, real processes in parallel (each key
    once): one line, exit code 2. The processes are given 300 s in all, not as a budget (they take a few seconds
    on a quiet machine) but so that a hang fails instead of stopping the suite, whatever the machine's load."""
    procs = {}
    for command, keys in (("run", ("initial.density", "velocity.speed_law")), ("info", ("velocity.speed",
                                                                                        "velocity.ux"))):
        for key in keys:
            here = tmp_path / f"{key}-{command}"
            here.mkdir()
            case = write_case(here, with_expression(key, "10**10**10"), GOOD_MESH)
            out = ["--out", str(here / "out"), "-q"] if command == "run" else []
            procs[here] = (key, subprocess.Popen([str(FEMCROWD), command, str(case), *out], stdout=subprocess.PIPE,
                                                 stderr=subprocess.PIPE, text=True))
    start = time.perf_counter()
    try:
        for here, (key, proc) in procs.items():
            stdout, stderr = proc.communicate(timeout=max(0.1, 300 - (time.perf_counter() - start)))
            assert proc.returncode == 2, (here, stderr)
            assert stdout == ""
            assert_refused(stderr, here / "case" / "case.toml", key, "10**10**10", "gives inf, not a finite number")
            assert not (here / "out").exists()
    finally:
        for _, proc in procs.values():
            proc.kill()
            proc.wait()


def test_an_expression_of_time_that_stops_being_finite_stops_the_run(tmp_path):
    """U finite at t = 0 (checked at load time), nan from the second step on: the run used to go on with t = nan
    and say "completed". Now it stops with one line naming the time, exit code 2, summary "failed", and the
    history written until then (finite) is kept."""
    source = "where(t > 0, log(-1), -1)"
    case = write_case(tmp_path, with_expression("velocity.ux", source).replace("end = 0.1", "end = 1"), GOOD_MESH)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(out), "-q"])
    assert result.exit_code == 2, result.output
    assert_refused(result.stderr, case / "case.toml", "velocity.ux", source,
                   "gives nan, not a finite number at 56 of 56 points, first at x = 0.125, y = 0, t = 0.0625")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"].startswith("failed: InputError: ") and "velocity.ux" in summary["status"]
    rows = [line.split(",") for line in (out / "history.csv").read_text().splitlines()[1:]]
    assert [float(row[0]) for row in rows] == [0.0, 0.0625]
    assert all(value not in ("nan", "inf") for row in rows for value in row)
