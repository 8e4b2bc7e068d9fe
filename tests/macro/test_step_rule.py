"""``time.cfl_quantile``: the implicit step set by a quantile of the cells' CFL-1 steps (docs/model.md, "Steps by
accuracy"): its step on a mesh whose cells are known, the invariants over a run, convergence on exact solution 3,
and the refusals of the explicit schemes."""

from unittest import TestCase

import numpy as np
import pytest
import skfem

from femcrowd.case import load_case
from femcrowd.driver import Simulation
from femcrowd.errors import InputError
from femcrowd.expressions import Expression
from femcrowd.macro import MacroSolver, MacroState
from femcrowd.macro.diagnostics import invariants
from femcrowd.macro.velocity import FieldVelocity
from femcrowd.mesh import Boundary, Domain

from ..support import CASES
from .test_exact import ExactRates

#: column widths (m) of a 1 m high strip: every triangle of a column of width w has the CFL-1 step w / 2 for U = (-1, 0)
WIDTHS = (0.1, 0.1, 0.2, 0.4, 0.8)


def graded_strip() -> Domain:
    """Columns of WIDTHS, two rows (four triangles per column: 20 cells), exit on the left."""
    x = np.concatenate([[0.0], np.cumsum(WIDTHS)])
    mesh = skfem.MeshTri.init_tensor(x, np.linspace(0.0, 1.0, 3))
    return Domain(mesh.with_boundaries({"exit": lambda p: np.isclose(p[0], 0.0)}), ["exit"])


def strip_solver(quantile, cfl=1.0):
    domain = graded_strip()
    velocity = FieldVelocity(domain, Expression("-1"), Expression("0"))
    solver = MacroSolver(domain, Boundary(domain), [velocity], "implicit", cfl=cfl, quantile=quantile)
    return solver, MacroState.initial(np.zeros((1, domain.ncells)), 1)


@pytest.mark.parametrize("quantile, cfl, expected", [
    (0.0, 1.0, 0.05),    # the smallest cell: w = 0.1 (the CFL step of the explicit scheme)
    (0.5, 1.0, 0.1),     # the median of 8 x 0.05, 4 x 0.1, 4 x 0.2, 4 x 0.4: 0.1
    (0.5, 3.0, 0.3),
    (1.0, 0.5, 0.2),     # the largest cell, w = 0.8
])
def test_the_step_is_cfl_times_the_quantile_of_the_cells_steps(quantile, cfl, expected):
    """The flux of U = (-1, 0) out of a triangle of a w x h rectangle is h, its area w h / 2: its CFL-1 step
    is w / 2 exactly, so the quantiles of the 20 cells' steps are known."""
    solver, state = strip_solver(quantile, cfl)
    scheme = solver.transports(state, solver.boundary.at(0.0))[0]
    assert np.allclose(np.sort(scheme.cell_dt), np.repeat(np.divide(WIDTHS, 2), 4), rtol=1e-12, atol=0)
    assert solver.stable_dt(state) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("case, cfl", [("room", 4.0), ("two-groups", 2.0)])
def test_invariants_hold_to_round_off_with_the_quantile_step(case, cfl):
    """Steps of cfl times the median cell's CFL step (far beyond the smallest cell's): the mass of each population
    plus what it evacuated is its initial mass to round-off, 0 <= rho <= 1, p >= 0, p (1 - rho) = 0."""
    loaded = load_case(CASES / case, ["scheme.transport=implicit", "time.cfl_quantile=0.5", f"time.cfl={cfl}"])
    model = Simulation(loaded).model
    solver, state, domain = model.solver, model.state, model.domain
    smallest = min(s.max_dt for s in solver.transports(state, solver.boundary.at(0.0)))
    m0 = state.rho @ domain.area
    largest = 0.0
    for _ in range(25):
        largest = max(largest, solver.step(state).dt)
        assert np.allclose(state.rho @ domain.area + state.evacuated.sum(axis=1), m0, rtol=0, atol=1e-12 * m0.sum())
        seen = invariants(domain, state)
        assert seen["min_density"] >= 0.0 and seen["max_density"] <= 1 + 1e-9 and seen["min_pressure"] >= 0.0
        assert seen["complementarity"] <= 1e-9 * max(seen["max_pressure"], 1.0)
    assert largest > 1.2 * cfl * smallest and state.evacuated.sum() > 0


class ConvergenceSaturatedEvacuationQuantileStep(ExactRates, TestCase):
    """Sol. 3 at the quantile rule's step (cfl 2 on the median cell): the evacuated mass still converges ~ h."""

    case = "saturated-exit"
    overrides = ("time.end=0.3", "scheme.transport=implicit", "time.cfl_quantile=0.5", "time.cfl=2")
    rates = {"evacuated_error": 0.8}
    decreasing = ("evacuated_error",)


@pytest.mark.parametrize("overrides, message", [
    (["time.cfl_quantile=0.5"], "must be 0 with scheme.transport = 'upwind'"),
    (["time.cfl_quantile=0.5", "scheme.transport=muscl"], "must be 0 with scheme.transport = 'muscl'"),
    (["time.cfl_quantile=0.5", "scheme.transport=implicit", "time.dt=0.01"], "not with time.dt"),
])
def test_the_quantile_step_is_refused_where_it_is_not_safe(overrides, message):
    """An explicit step is positive only within the smallest cell's CFL step; a fixed dt has no cfl to scale."""
    with pytest.raises(InputError, match=message) as raised:
        Simulation(load_case(CASES / "room", overrides))
    assert "time.cfl_quantile" in str(raised.value)
