"""femcrowd mesh / new / info and the CLI conventions (help with examples, one-line errors, exit codes)."""

import csv
import json
import re
import tomllib

import numpy as np
import pytest
import skfem
from click.testing import CliRunner

from femcrowd.case import load_case
from femcrowd.cli import main

from ..support import ROOT

# channel [0, 3] x [0, 1], exits at both ends, a round obstacle
PLAN = """
size = 0.2
[outer]
points = [[0, 0], [3, 0], [3, 1], [0, 1]]
[[exits]]
name = "west"
from = [0, 1]
to = [0, 0]
[[exits]]
name = "east"
from = [3, 0]
to = [3, 1]
[[holes]]
circle = { center = [2, 0.5], radius = 0.2 }
"""


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def history(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_mesh_new_and_run_a_floor_plan(tmp_path):
    """A floor plan -> femcrowd mesh -> femcrowd new -> femcrowd run; per-exit outflow in history.csv."""
    (tmp_path / "plan.toml").write_text(PLAN)
    msh = tmp_path / "meshes" / "plan.msh"
    result = invoke("mesh", tmp_path / "plan.toml", "-o", msh)
    assert result.exit_code == 0, result.output
    assert msh.is_file() and "west 1 m" in result.output and "east 1 m" in result.output
    mesh = skfem.MeshTri.load(str(msh))
    assert f"{mesh.t.shape[1]} triangles" in result.output

    case_dir = tmp_path / "case"
    result = invoke("new", case_dir, "--mesh", msh, "--model", "paper")   # rho_max 1: exact solution 3 below
    assert result.exit_code == 0, result.output
    case = load_case(case_dir)
    assert case["mesh"]["file"] == "../meshes/plan.msh"  # relative to the case directory
    assert sorted(case["boundary"]["exits"]) == ["east", "west"]
    assert case["velocity"]["type"] == "exits"
    text = (case_dir / "case.toml").read_text()
    assert text.count("#") > 20  # commented

    # exact solution 3 (k = 1, s0 = 1) on this channel: all the crowd leaves by the
    # west exit, pushed by the pressure; nothing reaches the east exit
    out = tmp_path / "out"
    result = invoke("run", case_dir, "--out", out, "-q", "--set", "time.end=0.3", "--set", 'velocity.type="field"',
                    "--set", 'velocity.ux="-(1 + x)"', "--set", 'initial.density="1.0 * (x < 1)"')
    assert result.exit_code == 0, result.output
    h = history(out / "history.csv")
    assert np.all(h["evacuated_east"] == 0)
    assert np.all(np.diff(h["evacuated_west"]) >= 0)
    assert np.allclose(h["evacuated_west"], h["evacuated"], rtol=1e-12, atol=0)
    assert h["max_pressure"].max() > 0.1  # the pressure part of the outflow is in the split
    s = 3 * np.exp(-0.15) - 2
    assert h["evacuated"][-1] == pytest.approx(1 - s, rel=0.05)


def test_new_refuses_to_overwrite(tmp_path):
    case_dir = tmp_path / "case"
    case_dir.mkdir()
    (case_dir / "case.toml").write_text("# mine\n")
    result = invoke("new", case_dir, "--mesh", ROOT / "meshes" / "two_exits.msh")
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and "already exists" in result.stderr
    assert (case_dir / "case.toml").read_text() == "# mine\n"


def test_new_case_without_exits_uses_a_field_velocity(tmp_path):
    result = invoke("new", tmp_path / "c", "--mesh", ROOT / "meshes" / "square.msh")
    assert result.exit_code == 0, result.output
    case = load_case(tmp_path / "c")
    assert case["boundary"]["exits"] == [] and case["velocity"]["type"] == "field"


def seconds(duration: str) -> float:
    """'12 s' or '1.5 min' (femcrowd info's durations) in seconds."""
    value, unit = duration.split()
    return float(value) * (60 if unit == "min" else 1)


def test_info_prints_config_mesh_statistics_and_estimate():
    result = invoke("info", ROOT / "cases" / "room")
    assert result.exit_code == 0, result.output
    out = result.output
    mesh = skfem.MeshTri.load(str(ROOT / "meshes" / "room_one_door.msh"))
    assert f"{mesh.t.shape[1]} triangles, {mesh.p.shape[1]} nodes, area 60 m^2" in out
    assert re.search(r"^\s+wall\s+31 m\s+wall$", out, re.M) and re.search(r"^\s+exit\s+1 m\s+exit$", out, re.M)
    assert 'density = "0.8 * (x < 4)"' in out and "empty_fraction = 0.0001" in out  # resolved, defaults filled
    assert "Delaunay: yes" in out
    angle = float(re.search(r"angles: min ([\d.]+) deg", out)[1])
    assert 20 < angle <= 60
    dt, steps = re.search(r"time step ([\d.e-]+) s -> about (\d+) steps", out).groups()
    assert int(steps) == pytest.approx(60 / float(dt), rel=1e-3)
    duration = r"([\d.e+-]+ (?:s|min))"   # 2 significant digits, in minutes from 60 s (a busy machine's run)
    total, startup, setup, loop = (seconds(d) for d in re.search(
        rf"run time of femcrowd run: about {duration} \(start-up {duration}, set-up {duration}, run {duration}\)",
        out).groups())
    # the four figures to 2 significant digits, each up to 5 % off (11 s for 11.4): the sum within 10 %
    assert min(startup, setup, loop) >= 0
    assert total == pytest.approx(startup + setup + loop, rel=0.1, abs=0.1)
    assert re.search(r"based on (the whole run timed here|\d+ steps to t = [\d.]+ s timed here)", out)
    assert "121 frames" in out


def config_block(out):
    """The resolved configuration printed by femcrowd info, read as TOML."""
    block = out.split("resolved configuration (TOML", 1)[1].split("\n", 1)[1].split("\n\n", 1)[0]
    return tomllib.loads(block)


def without_none(value):
    if isinstance(value, dict):
        return {k: without_none(v) for k, v in value.items() if v is not None}
    return [without_none(v) for v in value] if isinstance(value, list) else value


@pytest.mark.parametrize("case, people", [
    ("two-groups", r"people at t = 0: 56.1\d m\^2 at rho_max \(north 28.0\d, south 28.0\d\); with model.rho_max = 1"),
    ("bottleneck", r"people at t = 0: 90.04$"),   # rho_max = 5.4: people
    ("entrance", r"people at t = 0: 0; more arrive through \[\[sources\]\]$")])
def test_info_configuration_is_toml_and_people_are_counted(case, people):
    """The configuration reads back as the case's (populations with keys not set, [exact] not set, lists of
    tables); two populations of 0.7 on 4 x 10 m each, 28 m^2 at rho_max; 90.04 people in the bottleneck."""
    result = invoke("info", ROOT / "cases" / case)
    assert result.exit_code == 0, result.output
    assert config_block(result.output) == without_none(load_case(ROOT / "cases" / case).config)
    assert re.search(people, result.output, re.M), result.output


def test_info_counts_the_discs_a_micro_run_starts_with(tmp_path):
    out = invoke("info", ROOT / "cases" / "narrow-door-micro").output
    count = int(re.search(r"^people at t = 0: (\d+)$", out, re.M)[1])
    result = invoke("run", ROOT / "cases" / "narrow-door-micro", "--set", "time.end=0.05", "--out", tmp_path, "-q")
    assert result.exit_code == 0, result.output
    assert count == json.loads((tmp_path / "summary.json").read_text())["initial_count"] == 72


@pytest.mark.parametrize("old, new, key, message", [
    ("[[0, 0], [3, 0], [3, 1], [0, 1]]", "[[0, 0], [3, 1], [3, 0], [0, 1]]", "outer.points", "intersects itself"),
    ("from = [3, 0]", "from = [3.5, 0]", "exits[1]", "must lie on one straight edge"),
    ("center = [2, 0.5]", "center = [2, 1.5]", "holes[0]", "strictly inside the outer boundary")])
def test_bad_geometry_is_one_line_and_exit_2(tmp_path, old, new, key, message):
    """A self-intersecting outline, an exit off the boundary, a hole outside the floor."""
    (tmp_path / "bad.toml").write_text(PLAN.replace(old, new))
    result = invoke("mesh", tmp_path / "bad.toml")
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.output
    assert f"bad.toml: {key} = " in result.stderr and message in result.stderr
    assert not (tmp_path / "bad.msh").exists()


@pytest.mark.parametrize("command", ["run", "plot", "mesh", "new", "info"])
def test_every_command_has_help_with_examples(command):
    result = invoke(command, "--help")
    assert result.exit_code == 0
    assert "Example" in result.output


def test_main_help_documents_exit_codes():
    out = invoke("--help").output
    for code in ("0 ", "1 ", "2 ", "130"):
        assert f"  {code}" in out


@pytest.mark.parametrize("where", ["before", "after"])
def test_verbose_before_or_after_the_command(tmp_path, where):
    """`femcrowd -v run CASE` and `femcrowd run CASE -v`: the same log on stderr; without -v, none."""
    run = ["run", ROOT / "cases" / "room", "--set", "time.end=0.5", "--out", tmp_path / "out", "-q"]
    result = invoke(*(["-v", *run] if where == "before" else [*run, "-v"]))
    assert result.exit_code == 0, result.output
    assert re.search(r"^femcrowd: set up .*case.toml: mesh [\d.e-]+ s", result.stderr, re.M)
    assert re.search(r"^femcrowd: t = 0.5 s: mass 19.2", result.stderr, re.M)
    quiet = invoke(*run)
    assert quiet.exit_code == 0 and "set up" not in quiet.stderr


def test_every_command_takes_verbose():
    for name, command in main.commands.items():
        assert [p for p in command.params if p.name == "verbose" and "-v" in p.opts], name
        assert "-v, --verbose" in invoke(name, "--help").output, name
