"""The discs' desired direction at walls and corners (micro/clearance.py, docs/micro.md, "Walls and corners"): with
``micro.walls = "paper"`` a disc that turns around a thin wall's end can stay there for good (the direction points at
the end, which its centre cannot reach); with ``"clearance"`` the direction is that of the walking distance of disc
centres kept a radius from the walls, and every disc leaves."""

import logging

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.mesh.floorplan import build_mesh

from ..support import CASES

#: a 6 x 4 m room split at y = 2 by a 1 cm wall from the west wall to x = 5 (a 1 m gap at its east end); the exit on
#: the west wall just above it: the discs, below it, walk east, turn around its end and walk back west
UTURN = """size = 0.25

[outer]
points = [[0, 0], [6, 0], [6, 4], [0, 4]]

[[exits]]
name = "exit"
from = [0, 2.1]
to = [0, 3.1]

[[walls]]
points = [[0, 2], [5, 2]]
thickness = 0.01
"""

CASE = """[mesh]
file = "plan.msh"

[boundary]
exits = ["exit"]

[velocity]
type = "exits"
speed = 1.3

[model]
type = "micro"

[micro]
count = 20

[initial]
density = "0.5 * (y < 1.9) * (x < 4)"

[time]
end = 20.0

[output]
every = 1.0
"""

#: the wall's end, a corner of 1 cm
END = np.array([5.0, 2.0])


def uturn(tmp_path, *settings):
    (tmp_path / "plan.toml").write_text(UTURN)
    build_mesh(tmp_path / "plan.toml", out=tmp_path / "plan.msh")
    (tmp_path / "case.toml").write_text(CASE)
    return load_case(tmp_path, list(settings))


def run(case):
    simulation = Simulation(case)
    return simulation, simulation.run().history


def test_a_disc_stays_at_the_wall_end_it_turns_around(tmp_path):
    """The trap (issue 34 item 1, 37 item 3): with the density model's direction one disc of 20 is still inside at
    20 s, at the wall's end (its centre within 0.3 m of it, r = 0.2)."""
    simulation, history = run(uturn(tmp_path, "micro.walls='paper'"))
    sim = simulation.model.sim
    assert sim.count == 1 and history["count"][0] == 20
    assert np.hypot(*(sim.q[0] - END)) < 0.3


def test_with_the_clearance_every_disc_turns_around_the_wall_end(tmp_path):
    """The same scene with micro.walls = 'clearance': all 20 discs out, by 12 s (17.2 s on the thick-walled
    variant in the paper's direction: the last ones slid off the end slowly), no overlap, none lost through a
    wall; on the once refined mesh too (the paper's direction gets no better there)."""
    for refine in (0, 1):
        simulation, history = run(uturn(tmp_path, "micro.walls='clearance'", f"mesh.refine={refine}"))
        assert simulation.model.sim.count == 0 and simulation.model.sim.evacuated == 20
        assert simulation.model.evacuation.time < 12.0
        assert history["overlap_r"].max() <= 1e-9


def test_the_clearance_keeps_the_speed_and_turns_away_from_the_wall_end(tmp_path):
    """The desired velocities at the cell centroids: the same speed everywhere; in the cells where the centre of a
    disc touching the wall's end lies (0.15-0.3 m from it, r = 0.2), the paper's direction points at the end (its
    cosine with the way to the end reaches 0.99: the contact cancels it) and the clearance's stays 25 degrees or
    more off it (cosine below 0.9: a disc in contact keeps 44 % or more of its speed along the arc)."""
    paper = Simulation(uturn(tmp_path, "micro.walls='paper'")).model
    clear = Simulation(uturn(tmp_path, "micro.walls='clearance'")).model
    x = paper.domain.centroid
    U0, U1 = (model.desired.velocities[0](x, 0.0) for model in (paper, clear))
    assert np.allclose(np.hypot(*U0.T), np.hypot(*U1.T), rtol=1e-12)
    to_end = END - x
    d = np.hypot(*to_end.T)
    touching = (d > 0.15) & (d < 0.3)
    cosine = [np.einsum("ij,ij->i", U[touching], to_end[touching]) / (d[touching] * np.hypot(*U[touching].T))
              for U in (U0, U1)]
    assert cosine[0].max() > 0.99 and cosine[1].max() < 0.9


def test_the_route_choice_keeps_its_direction_with_a_warning(tmp_path, caplog):
    """The clearance applies to the walking distance of velocity.type = 'exits'; with the route choice (a cost of
    the crowd's) the direction is kept, and a warning says so."""
    route = "velocity.route='congestion'"
    with caplog.at_level(logging.WARNING, logger="femcrowd"):
        clear = Simulation(uturn(tmp_path, "micro.walls='clearance'", route)).model
    assert "micro.walls = 'clearance' applies to velocity.type = 'exits' without route choice" in caplog.text
    paper = Simulation(uturn(tmp_path, route)).model
    x = paper.domain.centroid
    assert np.array_equal(clear.desired.velocities[0](x, 0.0), paper.desired.velocities[0](x, 0.0))


@pytest.mark.slow
def test_every_disc_leaves_the_three_storeys(tmp_path):
    """cases/three-storeys with 61 discs, five seeds: with the paper's direction 3 stay at the stairs' U-turns in
    every seed (58 out at 120 s); with the clearance all 61 are out."""
    for seed in range(1, 6):
        case = load_case(CASES / "three-storeys", ["model.type='micro'", "initial.people=61", f"micro.seed={seed}",
                                                   "micro.walls='clearance'"])
        simulation, history = run(case)
        assert simulation.model.sim.evacuated == 61 and simulation.model.sim.count == 0, seed
        assert history["overlap_r"].max() <= 1e-9
