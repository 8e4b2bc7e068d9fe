"""The phases of a run (femcrowd/timer.py): a phase timed inside another is booked to itself alone."""

import time

from femcrowd.timer import Stopwatch, Timer


def test_nested_phases_are_booked_once():
    timer, clock = Timer(), Stopwatch()
    with timer("projection"):
        time.sleep(0.02)
        with timer("measurements"):
            time.sleep(0.05)
    total = clock.seconds
    assert timer["measurements"] >= 0.05 and timer["projection"] >= 0.02
    # the projection's seconds leave out the measurements': the two add up to the time spent
    assert abs(timer["projection"] + timer["measurements"] - total) < 1e-3
