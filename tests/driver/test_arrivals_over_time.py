"""Arrivals over time (docs/scenes.md, issue 34 item 4): a source's flow, or its rate for the whole entrance, given
as an expression of t or a table of (t, value) pairs, or a number of people: the people who entered equal the
integral of the flow, to round-off in the density model (nothing blocks the entrance) and as the floor of it, the
arrivals' rule, for the discs."""

import math

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.profiles import Profile

from ..support import CASES
from .test_scenes import assert_invariants, channel, macro_run  # noqa: F401 (channel: a fixture)


def test_a_table_is_integrated_exactly_with_its_jumps_and_zero_outside():
    """g = 0 before 1, 0 -> 4 on [1, 3], a jump to 1 at 3, 1 until 5, 0 after: its integral over any window
    is the area under the polygon."""
    g = Profile([[1, 0], [3, 4], [3, 1], [5, 1]])
    assert g.amount(0.0, 10.0) == pytest.approx(4.0 + 2.0, rel=1e-15)
    assert g.amount(2.0, 4.0) == pytest.approx(0.5 * (2 + 4) * 1 + 1.0, rel=1e-15)
    assert g.amount(-2.0, 0.5) == 0.0 and g.amount(5.0, 7.0) == 0.0
    np.testing.assert_array_equal(g(np.array([0.5, 2.0, 4.0, 6.0])), [0.0, 2.0, 1.0, 0.0])
    assert g.last == 5.0


def test_an_expression_is_integrated_to_round_off_over_a_step():
    g = Profile("2 + sin(t)")
    assert g.amount(0.3, 0.35) == pytest.approx(0.1 + math.cos(0.3) - math.cos(0.35), rel=1e-14)


def exact_channel_inflow(channel, source, integral):  # noqa: F811
    """The empty 4 m x 1 m channel (U = 1): every person of `source` enters (the flow stays below the speed x
    rho_max the entrance takes), the inflow is the integral to round-off, the balance holds on every row."""
    h = macro_run(channel, {"sources": [{"boundary": "entrance", **source}]}).history
    assert h["queued"].max() == 0.0
    assert h["inflow"][-1] == pytest.approx(integral, rel=1e-13, abs=0)
    assert h["mass"][-1] == pytest.approx(integral, rel=1e-12)
    assert_invariants(h)
    return h


def test_macro_inflow_of_an_expression_is_its_integral(channel):  # noqa: F811
    h = exact_channel_inflow(channel, {"flow": "0.2 + 0.1 * sin(3 * t)", "start": 0.5, "end": 1.5},
                             0.2 + 0.1 / 3 * (math.cos(1.5) - math.cos(4.5)))
    assert np.all(h["inflow"][h["time"] <= 0.5] == 0.0)


def test_macro_inflow_of_a_table_is_its_integral_and_ends_with_it(channel):  # noqa: F811
    """A table with a jump, ending at 1.5 s (the source's end when none is given, not time.end = 2)."""
    case = load_case(channel, {"sources": [{"boundary": "entrance", "flow": [[0.2, 0], [1, 0.4], [1, 0.1],
                                                                             [1.5, 0.3]]}]})
    assert Simulation(case).scene.sources[0].end == 1.5
    exact_channel_inflow(channel, {"flow": [[0.2, 0], [1, 0.4], [1, 0.1], [1.5, 0.3]]}, 0.8 * 0.2 + 0.5 * 0.2)


def test_a_rate_is_for_the_whole_entrance_and_people_spread_over_the_span():
    """cases/entrance (a 2 m entrance, rho_max 5.4): a timetable of persons per second, and 20 people over
    [0, 4] s, each enter whole; 3 persons/s at most, 1.5 per metre, far below what the entrance takes."""
    for source, integral in (({"rate": [[0, 0], [2, 3], [4, 0]]}, 6.0), ({"people": 20, "end": 4.0}, 20.0)):
        case = load_case(CASES / "entrance", {"time.end": 4.5, "sources": [{"boundary": "entrance", **source}]})
        h = Simulation(case).run(stop_when_empty=False).history
        assert h["queued"].max() == 0.0
        assert h["inflow"][-1] == pytest.approx(integral, rel=1e-13, abs=0)
        assert h["mass_error"].max() < 1e-12


@pytest.mark.parametrize("source, integral", [
    ({"rate": "3 + 2 * sin(t)"}, lambda t: 3 * t + 2 * (1 - np.cos(t))),
    ({"rate": [[0, 0], [2, 8], [3, 0]]}, lambda t: np.where(t < 2, 2 * t * t, 12 - 4 * (3 - t) ** 2)),
    ({"people": 7, "end": 2.0}, lambda t: 3.5 * np.minimum(t, 2.0)),
])
def test_micro_discs_placed_are_the_floor_of_the_integral(channel, source, integral):  # noqa: F811
    """Discs (r = 0.1) through the 1 m entrance over [0, 3] s: on every row the discs placed and waiting are
    the whole part of the integral of the rate (discs per second: one disc a person), none overlapping."""
    case = load_case(channel, {"model.type": "micro", "micro.radius": 0.1, "time.end": 3.0,
                               "sources": [{"boundary": "entrance", **source}]})
    h = Simulation(case).run(stop_when_empty=False).history
    np.testing.assert_array_equal(h["inflow"] + h["queued"], np.floor(integral(h["time"]) + 1e-9))
    assert h["queued"][-1] == 0 and h["inflow"][-1] == np.floor(integral(3.0) + 1e-9)
    assert np.all(h["count"] + h["evacuated"] == h["inflow"])
    assert h["max_overlap"].max() < 1e-3 * 0.1
