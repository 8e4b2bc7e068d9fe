"""Stair speeds (macro/stairs.py, docs/floors.md "Stair speeds"): a stair with up and down speeds walks each
direction at its own speed, the published ones by name; exact walk times as in tests/mesh/test_building.py."""

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.macro.stairs import STAIR_SPEEDS

from ..support import CASES

#: the corridor of tests/mesh/test_building.py (upper floor x in [0, 4] at z = 3, a stair over x in [4, 8], 5 m
#: along its slope, the ground floor x in [8, 12]) with an exit at each end: "top" at x = 0, "exit" at x = 12
BOTH_ENDS = """
size = 0.25
[[floors]]
name = "upper"
elevation = 3.0
outer.points = [[0, 0], [4, 0], [4, 2], [0, 2]]
exits = [{name = "top", from = [0, 2], to = [0, 0]}]
[[floors]]
name = "ground"
elevation = 0.0
outer.points = [[8, 0], [12, 0], [12, 2], [8, 2]]
exits = [{name = "exit", from = [12, 0], to = [12, 2]}]
[[stairs]]
name = "stair"
lower = "ground"
upper = "upper"
foot = [[8, 2], [8, 0]]
head = [[4, 0], [4, 2]]
"""
CASE = """
[mesh]
file = "building.msh"
[boundary]
exits = ["{exit}"]
[velocity]
speed = 1.3
speeds = {{ stair = {{ up = "weidmann-up", down = "rimea-down" }} }}
[initial]
density = "{density}"
[time]
end = 30
[output]
every = 30
"""


@pytest.fixture(scope="module")
def building(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stairs")
    (folder / "building.toml").write_text(BOTH_ENDS)
    result = CliRunner().invoke(main, ["mesh", str(folder / "building.toml")])
    assert result.exit_code == 0, result.output
    return folder


def median(folder, exit, density):
    (folder / "case.toml").write_text(CASE.format(exit=exit, density=density))
    h = Simulation(load_case(folder)).run().history
    assert np.abs(h["mass"] + h["evacuated"] - h["mass"][0]).max() <= 1e-14 * h["mass"][0]
    assert h["max_density"].max() < 1.0 and h["min_density"].min() >= 0.0
    return float(np.interp(0.5 * h["mass"][0], h["evacuated"], h["time"]))


@pytest.mark.parametrize(("exit", "density", "before", "speed", "after"), [
    ("top", "0.2 * (x >= 10) * (x <= 11)", 2.5, STAIR_SPEEDS["weidmann-up"], 4.0),     # up: 0.61 m/s
    ("exit", "0.2 * (x >= 1) * (x <= 2)", 2.5, STAIR_SPEEDS["rimea-down"], 4.0),       # down: 0.75 m/s
])
def test_a_stair_is_walked_up_and_down_at_its_own_speeds(building, exit, density, before, speed, after):
    """The same stair, { up = "weidmann-up", down = "rimea-down" }: the person in the middle of a crowd on the ground
    floor heading for the exit upstairs walks 2.5 m at 1.3 m/s, 5 m up the slope at 0.61 m/s, 4 m at 1.3 m/s; one
    on the upper floor heading down 2.5 m, 5 m down at 0.75 m/s, 4 m: half the crowd is out at that time (to the
    upwind scheme's diffusion, as the walk of tests/mesh/test_building.py)."""
    exact = before / 1.3 + 5.0 / speed + after / 1.3
    assert median(building, exit, density) == pytest.approx(exact, rel=2e-3)


@pytest.mark.parametrize(("exit", "climbs", "speed"), [("exit_top", True, 0.61), ("exit_bottom", False, 0.75)])
def test_the_speed_on_the_stair_is_that_of_the_direction_of_the_route(exit, climbs, speed):
    """RiMEA 2 and 3's stair (meshes/rimea/test02_stair.toml, an exit above and one below) with { up =
    "weidmann-up", down = "rimea-down" }: heading for the exit above, U climbs every cell of the stair at 0.61 m/s
    along its slope (the lift of U, |U|^2 + (s . U)^2 = v^2); heading below, it descends at 0.75 m/s."""
    simulation = Simulation(load_case(CASES / "rimea" / "test02-stair-up", {
        "boundary.exits": [exit], "velocity.speeds": {"stair": {"up": "weidmann-up", "down": "rimea-down"}}}))
    velocity = simulation.model.solver.velocities[0]
    stair = np.asarray(velocity.domain.mesh.subdomains["stair"])
    u = velocity.cells(simulation.scene.boundary.at(0.0))[stair]
    rise = np.einsum("ij,ij->i", velocity.domain.slope[stair], u)
    assert np.all(rise > 0) if climbs else np.all(rise < 0)
    assert np.allclose(np.sqrt((u * u).sum(axis=1) + rise ** 2), speed, rtol=1e-12, atol=0)


def test_the_published_speeds_are_the_cited_figures():
    """The names give the figures of docs/floors.md: Burghardt et al. (2014) Table 1 upward, GOST 12.1.004-91's free
    speeds (m/min / 60), JuPedSim's RiMEA 2 and 3."""
    assert STAIR_SPEEDS == {"fruin-up": 0.55, "weidmann-up": 0.61, "predtechenskii-up": 0.63,
                            "nelson-mowrer-up": 0.80, "gost-free-up": 1.0, "gost-free-down": 100 / 60,
                            "rimea-up": 0.5, "rimea-down": 0.75}


@pytest.mark.parametrize(("speeds", "key", "message"), [
    ('{ stair = "weidman-up" }', "velocity.speeds.stair", "'weidmann-up'"),
    ("{ stair = { up = 0.6 } }", "velocity.speeds.stair", "{ up = speed, down = speed }"),
    ("{ stair = { up = 0.6, down = -1 } }", "velocity.speeds.stair.down", "a speed >= 0"),
    ("{ upper = { up = 0.6, down = 0.7 } }", "velocity.speeds.upper", "need a stair"),
])
def test_a_bad_stair_speed_is_one_line_naming_the_key(building, speeds, key, message):
    (building / "case.toml").write_text(CASE.format(exit="exit", density="0.2"))
    out = building / "bad"
    result = CliRunner().invoke(main, ["run", str(building), "--set", f"velocity.speeds={speeds}", "--out", str(out),
                                       "-q"])
    assert result.exit_code == 2 and f": {key} = " in result.output and message in result.output, result.output
    assert "Traceback" not in result.output and not out.exists()
