"""The phases of a run (femcrowd/timer.py): a phase timed inside another is booked to itself alone."""

import femcrowd.timer
from femcrowd.timer import Stopwatch, Timer


def test_nested_phases_are_booked_once(monkeypatch):
    """On a clock that moves only when told (the real one runs on under a loaded machine's scheduler): 0.02 s in
    the projection, 0.05 s in the measurements inside it; the two phases add up to the time spent."""
    now = [100.0]
    monkeypatch.setattr(femcrowd.timer.time, "perf_counter", lambda: now[0])

    def spend(seconds):
        now[0] += seconds

    timer, clock = Timer(), Stopwatch()
    with timer("projection"):
        spend(0.02)
        with timer("measurements"):
            spend(0.05)
    assert abs(timer["measurements"] - 0.05) < 1e-12
    assert abs(timer["projection"] - 0.02) < 1e-12
    assert abs(timer["projection"] + timer["measurements"] - clock.seconds) < 1e-12
