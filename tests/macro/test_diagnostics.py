"""The invariants of a macro state (macro/diagnostics.py) against values counted by hand."""

import numpy as np
import pytest

from femcrowd.macro import MacroState
from femcrowd.macro.diagnostics import SATURATED, invariants

from ..support import unit_square


def two_populations(domain):
    """A state of two populations with a saturated cell, pressure there and an exit's evacuated mass."""
    n = domain.ncells
    rho = np.zeros((2, n))
    rho[0, :n // 2], rho[1, n // 4:] = 0.5, 0.25
    rho[:, 3] = 0.5
    state = MacroState.initial(rho, 1, ("a", "b"))
    state.p[3], state.evacuated[:] = 2.0, [[0.1], [0.2]]
    return state


def test_invariants_of_a_state_counted_by_hand():
    domain = unit_square(8)
    state = two_populations(domain)
    d, rho = invariants(domain, state), state.rho.sum(axis=0)
    assert d["mass"] == pytest.approx(domain.area @ rho, rel=1e-15)
    assert d["evacuated"] == pytest.approx(0.3)
    assert (d["max_density"], d["min_density"], d["max_pressure"], d["min_pressure"]) == (1.0, rho.min(), 2.0, 0.0)
    assert d["saturated_area"] == domain.area[rho >= SATURATED].sum() == domain.area[3]
    assert d["pressure_unsaturated"] == 0.0 and d["complementarity"] == 0.0 and d["non_finite"] == 0
    state.p[0] = -0.5   # p on a cell off the saturated zone (rho = 0.5 there)
    d = invariants(domain, state)
    assert d["pressure_unsaturated"] == 0.5 and d["complementarity"] == 0.25 and d["min_pressure"] == -0.5


@pytest.mark.parametrize("where", ["rho nan", "rho inf", "rho +inf -inf", "p nan", "p -inf"])
def test_every_nan_and_inf_is_counted(where):
    """NaN or inf in one population's density (two of opposite signs in one cell: a NaN total) or in p: counted
    one by one, though the mass and the extremes then hide which entries they are."""
    domain = unit_square(8)
    state = two_populations(domain)
    bad = {"rho nan": (state.rho[1], [0, 9], np.nan), "rho inf": (state.rho[0], [2], np.inf),
           "rho +inf -inf": (state.rho, ([0, 1], [5, 5]), np.array([np.inf, -np.inf])),
           "p nan": (state.p, [1, 2, 3], np.nan), "p -inf": (state.p, [7], -np.inf)}[where]
    bad[0][bad[1]] = bad[2]
    expected = np.count_nonzero(~np.isfinite(state.rho)) + np.count_nonzero(~np.isfinite(state.p))
    assert expected > 0 and invariants(domain, state)["non_finite"] == expected
