"""The run time of femcrowd info (driver/estimate.py): a run that ends within the budget is measured whole, a
longer one extrapolated from its prefix to the time the crowd is out; benchmarks/estimate.py is the real measure
(every shipped case, fresh processes), this checks the structure, which holds whatever the load of the machine."""

import math

import pytest

import femcrowd
from femcrowd.driver import estimate

from ..support import CASES


def test_a_short_run_is_measured_whole():
    """cases/room to t = 2 s: the prefix is the whole run (its steps, its end); the parts add up."""
    case = femcrowd.load_case(CASES / "room", {"time.end": 2})
    e = estimate.case_info(case, startup=0.5, budget=math.inf)["estimate"]   # whatever the load
    run = femcrowd.Simulation(case).run()
    assert e["measured"] and e["end"] == "the whole run" and e["end_time"] == 2
    assert e["steps"] == e["prefix_steps"] == len(run.history["time"]) - 1
    assert e["seconds"] == pytest.approx(0.5 + e["setup_seconds"] + e["loop_seconds"])
    assert "seconds_to_end" not in e


class StepClock:
    """A stopwatch that advances 1/256 s each time it is read (twice a step in the timed prefix): the prefix of a
    0.3 s budget is the same 38 steps whatever the load of the machine (on the real clock, 26 to 47 steps here)."""

    def __init__(self):
        self.reads = 0

    @property
    def seconds(self):
        self.reads += 1
        return self.reads / 256


def test_a_longer_run_is_extrapolated_to_the_crowd_out(monkeypatch):
    """cases/narrow-door timed for 0.3 s only (of a clock that counts the steps): the end is the crowd out, near
    the run's evacuation time, its steps near the run's, and the run time the sum of its parts. How near the
    seconds come to a real run's is a measure of a quiet machine, not a test (a 0.3 s prefix timed while the
    suite's other worker runs was 3.3 times a run timed after it): benchmarks/estimate.py times every shipped
    case in fresh processes."""
    case = femcrowd.load_case(CASES / "narrow-door")
    monkeypatch.setattr(estimate, "Stopwatch", StepClock)
    e = estimate.case_info(case, budget=0.3)["estimate"]
    monkeypatch.undo()
    assert e["prefix_steps"] == 38
    run = femcrowd.Simulation(case).run(out=None)
    evacuation = run.summary["evacuation_time"]
    assert not e["measured"] and e["end"].startswith("crowd out") and e["prefix_time"] < evacuation
    assert 0.6 * evacuation < e["end_time"] < 1.6 * evacuation
    assert 0.6 < e["steps"] / (len(run.history["time"]) - 1) < 1.6
    assert min(e["startup_seconds"], e["setup_seconds"], e["loop_seconds"], e["prefix_seconds"]) >= 0
    assert e["seconds"] == pytest.approx(e["startup_seconds"] + e["setup_seconds"] + e["loop_seconds"])
    assert e["seconds_to_end"] > e["seconds"]   # time.end = 40 s is further
