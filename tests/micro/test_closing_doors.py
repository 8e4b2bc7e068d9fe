"""A door that closes while discs stand in its doorway (driver/micro_model.py, MicroModel._doors): it stays open
for them until its doorway is clear, then closes; no disc ever overlaps the wall it becomes (docs/micro.md, "Doors
that close"). Before, the door closed on them: overlaps of 0.64 r, removed by 1e-3 r per step."""

import logging

import numpy as np

from femcrowd import Simulation, load_case

from ..support import CASES

#: the exit of cases/narrow-door-micro closes at 6.15 s, when a disc of the jam stands in its doorway
CLOSING = "boundary.open={exit=[[0, 6.15]]}"


def run(*overrides):
    simulation = Simulation(load_case(CASES / "narrow-door-micro", list(overrides)))
    return simulation, simulation.run().history


def door_is_a_wall(simulation) -> bool:
    """Is the middle of the door, (8, 2.5), on a wall of the discs?"""
    return bool(simulation.model.sim.contacts.walls.distance([[8.0, 2.5]])[0] == 0)


def test_a_door_stays_open_while_a_disc_stands_in_it(caplog):
    """No exit left after 6.15 s: every disc stands still (U = 0), those in the doorway too, and the door stays
    open for them, with a warning; no overlap at any step (before: 0.64 r at 6.25 s, 0.61 r at the end)."""
    with caplog.at_level(logging.WARNING, logger="femcrowd"):
        simulation, history = run(CLOSING, "time.end=6.5")
    assert history["overlap_r"].max() <= 1e-9
    assert simulation.model.exits.open == ("exit",) and simulation.model._occupied("exit")
    assert not door_is_a_wall(simulation)
    messages = [r.getMessage() for r in caplog.records]
    assert messages[0] == ("exit 'exit' is to close at t = 6.15 s while discs stand in its doorway: it stays open "
                           "until they have left it")
    inside = int(history["count"][-1])   # how many of the jam are out by then is the run's (round-off decides)
    assert 0 < inside < history["count"][0]
    assert messages[1:] == [f"{CASES / 'narrow-door-micro' / 'case.toml'}: {inside} people can never leave "
                            f"(t = 6.5 s): {inside} people behind exits closed for good (exit)"]


def test_a_door_closes_once_its_doorway_is_clear(caplog):
    """The discs turn back at 6.15 s (U = (1, 0), then (-1, 0)): the door closes at the first step its doorway
    is clear, 6.25 s (before: at 6.15 s, on the disc in it), a wall from then on (nobody leaves through it), and
    no disc overlaps it."""
    with caplog.at_level(logging.INFO, logger="femcrowd"):
        simulation, history = run(CLOSING, "time.end=7", "velocity.type=field", "velocity.ux=1 - 2 * (t >= 6.15)")
    assert [r.getMessage() for r in caplog.records if "exit 'exit'" in r.getMessage()][-1] == \
        "exit 'exit' closed at t = 6.25 s"
    assert history["overlap_r"].max() <= 1e-9
    assert simulation.model.exits.open == () and door_is_a_wall(simulation)
    after = history["time"] > 6.25 + 1e-9
    assert np.ptp(history["evacuated"][after]) == 0 and history["evacuated"][-1] > 0
