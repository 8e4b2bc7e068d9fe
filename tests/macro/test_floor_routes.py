"""The routes over floors (docs/floors.md, "Routes over floors"): the walking distance over two stairs of different
lengths is the unfolded walk, the crowd splits between them as that distance says, and the route choice that sees
the crowd (velocity.route = "congestion") evens the split out."""

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main

#: an upper floor of 4 m x 6 m at z = 3 and two stairs down to the ground floor, where the exit is (x = 14): "short"
#: from y in [0, 2] (4 m of run, 5 m along the slope) and "long" from y in [4, 6] (6 m of run, 45^(1/2) m along the
#: slope), whose foot is 2 m nearer the exit
TWO_STAIRS = """
size = 0.25
[[floors]]
name = "upper"
elevation = 3.0
outer.points = [[0, 0], [4, 0], [4, 6], [0, 6]]
[[floors]]
name = "ground"
elevation = 0.0
outer.points = [[8, 0], [14, 0], [14, 6], [10, 6], [10, 4], [8, 4]]
exits = [{name = "exit", from = [14, 0], to = [14, 6]}]
[[stairs]]
name = "short"
lower = "ground"
upper = "upper"
foot = [[8, 2], [8, 0]]
head = [[4, 0], [4, 2]]
[[stairs]]
name = "long"
lower = "ground"
upper = "upper"
foot = [[10, 6], [10, 4]]
head = [[4, 4], [4, 6]]
"""
LONG = np.hypot(6.0, 3.0)
#: 48 persons on the upper floor; capacities on the stairs' heads that never bind (20 persons/s), for their flows
CASE = """
[mesh]
file = "building.msh"
[boundary]
exits = ["exit"]
capacity = { short_head = 10.0, long_head = 10.0 }
[model]
rho_max = 5.4
[velocity]
speed = 1.3
speeds = { short = 0.65, long = 0.65 }
[initial]
regions = { upper = 2.0 }
[time]
end = 30
[output]
every = 30
"""


@pytest.fixture(scope="module")
def building(tmp_path_factory):
    folder = tmp_path_factory.mktemp("two-stairs")
    (folder / "building.toml").write_text(TWO_STAIRS)
    result = CliRunner().invoke(main, ["mesh", str(folder / "building.toml")])
    assert result.exit_code == 0, result.output
    (folder / "case.toml").write_text(CASE)
    return folder


def walks(x, y):
    """The exact walk to the exit from (x, y) on the upper floor over each stair: to the nearest point of its head,
    then straight down it and across the ground floor (11 m over the short stair, LONG + 4 m over the long one)."""
    def to_head(low, high):
        return np.hypot(4.0 - x, np.clip(y, low, high) - y)
    return to_head(0.0, 2.0) + 11.0, to_head(4.0, 6.0) + LONG + 4.0


@pytest.fixture(scope="module")
def runs(building):
    """Per route, the simulation and its history."""
    simulations = {route: Simulation(load_case(building, {"velocity.route": route}))
                   for route in ("shortest", "congestion")}
    return {route: (simulation, simulation.run().history) for route, simulation in simulations.items()}


def test_the_distance_over_two_stairs_is_the_unfolded_walk(runs):
    """d at the nodes of the stairs and the ground floor is the unfolded length of the walk (to round-off: straight
    paths to a straight exit); on the upper floor min of the walks over the two stairs, to a quarter of the cell
    size (the eikonal solver's first-order error at the fan of a head's corner and along the watershed)."""
    velocity = runs["shortest"][0].model.solver.velocities[0]
    domain = velocity.domain
    x, y = domain.points.T
    z = domain.z
    d = next(iter(velocity.distance.values()))
    ground, upper = z == 0.0, z == 3.0
    short, long = ~ground & ~upper & (y <= 2.0), ~ground & ~upper & (y >= 4.0)
    assert np.allclose(d[ground], 14.0 - x[ground], rtol=0, atol=1e-6)
    assert np.allclose(d[short], 6.0 + z[short] / 3.0 * 5.0, rtol=0, atol=1e-6)
    assert np.allclose(d[long], 4.0 + z[long] / 3.0 * LONG, rtol=0, atol=1e-6)
    assert np.allclose(d[upper], np.minimum(*walks(x[upper], y[upper])), rtol=0, atol=0.25 * 0.25)


def passed(history) -> dict:
    """The people who went down each stair: the flow through its head summed over the steps."""
    t = history["time"]
    return {name: float(np.sum(history[f"flow_{name}_head"][1:] * np.diff(t))) for name in ("short", "long")}


def test_the_crowd_splits_between_the_stairs_as_the_walking_distance_does(runs):
    """With the shortest route each person goes down the stair of the shorter walk: the people who pass the long
    stair are those of the upper floor's cells nearer the exit over it (26.8 of 48; measured over the slope: with
    the stairs' lengths in plan, 6 m, it would be 33.8), although the crowd jams at both heads (rho_max)."""
    simulation, h = runs["shortest"]
    domain = simulation.model.solver.velocities[0].domain
    cells = domain.mesh.subdomains["upper"]
    over_short, over_long = (w[domain.triangles[cells]].mean(axis=1) for w in walks(*domain.points.T))
    expected = 2.0 * domain.area[cells][over_long < over_short].sum()
    split = passed(h)
    assert split["long"] == pytest.approx(expected, abs=0.5) and expected == pytest.approx(26.79, abs=0.01)
    assert split["short"] + split["long"] == pytest.approx(h["evacuated"][-1], rel=1e-12)
    assert h["max_density"].max() == pytest.approx(5.4) and max(h["flow_short_head"].max(),
                                                                 h["flow_long_head"].max()) < 20.0


def test_the_route_choice_over_floors_evens_the_split_out(runs):
    """The route that sees the crowd (Hughes' cost 1 / (1 - rho) over the surface) sends people from the larger
    crowd (the long stair's basin holds more) to the short stair: the split is more even than by the walking
    distance (25.1 / 23.1 against 26.9 / 21.0); mass is conserved through the folds, p >= 0. (The crowd is out
    later, 90 % at 18.8 s against 17.0 s: the cost counts the density of a crowd that walks at its desired speed
    until it saturates; docs/floors.md, "Routes over floors".)"""
    shortest, h = runs["shortest"][1], runs["congestion"][1]
    split, by_distance = passed(h), passed(shortest)
    assert abs(split["long"] - split["short"]) < abs(by_distance["long"] - by_distance["short"]) - 2.0
    assert np.abs(h["mass"] + h["evacuated"] - h["mass"][0]).max() <= 1e-12 * h["mass"][0]
    assert h["min_pressure"].min() >= 0.0 and h["min_density"].min() >= 0.0
