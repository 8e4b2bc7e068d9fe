"""A run says once, with the time, when a step breaks the invariants of docs/model.md ("What every run shows")."""

import logging

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.driver.macro_model import INVARIANT_TOL, broken_invariants

from ..support import CASES

KEPT = {"mass_error": 1e-15, "complementarity": 1e-13, "max_pressure": 3.0, "min_density": 0.0}


@pytest.mark.parametrize("key, value, says", [
    ("mass_error", 10 * INVARIANT_TOL, "mass + evacuated - supplied"),
    ("complementarity", 0.74, "complementarity"),
    ("min_density", -1.82, "density -1.82 < 0"),
])
def test_each_broken_invariant_is_named(key, value, says):
    assert broken_invariants(KEPT, 5.4) == ""
    assert says in broken_invariants({**KEPT, key: value}, 5.4)


def test_complementarity_is_judged_against_the_largest_pressure():
    """p (1 - rho) of round-off grows with p: 1e-8 of a pressure of 100 is not broken."""
    assert broken_invariants({**KEPT, "complementarity": 5e-7, "max_pressure": 100.0}, 5.4) == ""
    assert broken_invariants({**KEPT, "complementarity": 5e-7, "max_pressure": 1.0}, 5.4) != ""


def test_a_run_that_loses_mass_says_so_once_with_the_time(caplog):
    model = Simulation(load_case(CASES / "room")).model
    with caplog.at_level(logging.WARNING, logger="femcrowd"):
        model.step(np.inf)
        model.row()
        assert not caplog.records   # a step of the room keeps its invariants
        model.state.rho[0, np.argmax(model.state.rho[0])] = -0.5   # a cell drained below zero
        model.row()
        model.row()
    warnings = [r.getMessage() for r in caplog.records]
    assert len(warnings) == 1
    assert warnings[0].startswith(f"t = {model.t:.6g} s:") and "< 0" in warnings[0]
    assert "mass + evacuated - supplied" in warnings[0]
