"""The LWR prediction (macro/transport/lwr.py): bounds at the CFL limit, mass, the projection skipped when
no population pushes at saturation and used when one does."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.macro import MacroSolver, MacroState
from femcrowd.macro.speed_law import SpeedLaw
from femcrowd.macro.velocity import FieldVelocity
from femcrowd.mesh import Boundary

from ..support import CASES, unit_square

#: a flux r f(r) with two humps (f = 1 until 0.3, 0.2 on [0.4, 0.9], 0 at 1): the downstream-speed flux
HUMPS = "where(rho < 0.3, 1, where(rho < 0.4, 1 - 8 * (rho - 0.3), where(rho < 0.9, 0.2, 2 * (1 - rho))))"


def field(domain, ux, uy):
    return FieldVelocity(domain, Expression(ux), Expression(uy))


def run_steps(domain, velocities, laws, rho0, steps=150, cfl=1.0):
    """Steps of the solver at time.cfl; the states' totals, smallest population and mass balance."""
    boundary = Boundary(domain)
    state = MacroState.initial(rho0, len(domain.exit_names), [f"p{i}" for i in range(len(rho0))])
    solver = MacroSolver(domain, boundary, velocities, cfl=cfl, laws=laws)
    mass0 = rho0 @ domain.area
    worst = {"max": 0.0, "min": 0.0, "mass": 0.0, "projection": 0}
    for _ in range(steps):
        info = solver.step(state)
        worst["max"] = max(worst["max"], state.density.max())
        worst["min"] = min(worst["min"], state.rho.min())
        balance = state.rho @ domain.area + state.evacuated.sum(axis=1) - mass0
        worst["mass"] = max(worst["mass"], np.abs(balance).max() / mass0.max())
        worst["projection"] += info.iterations
    return worst, solver


@pytest.mark.parametrize("law", ["linear", "weidmann", HUMPS])
def test_one_population_stays_in_bounds_at_the_cfl_limit_without_projection(law):
    """A compressive U (everyone pushed to the middle of the top side) on dense random data, at time.cfl = 1."""
    domain = unit_square(16, exits=["right"])
    rho0 = np.random.default_rng(1).uniform(0.3, 1.0, domain.ncells)
    U = field(domain, "(0.5 - x) * 4", "1 + 0 * x")
    worst, solver = run_steps(domain, [U], [SpeedLaw(law, 5.4)], rho0[None])
    assert not solver.needs_projection and not solver._projections      # never built
    assert worst["projection"] == 0
    assert worst["max"] <= 1.0 + 1e-14 and worst["min"] >= 0.0
    assert worst["mass"] < 1e-13


def test_the_flux_is_chosen_by_the_shape_of_g():
    domain = unit_square(4, exits=["right"])
    U = field(domain, "1", "0")
    state = MacroState.initial(np.zeros((2, domain.ncells)), 1)
    solver = MacroSolver(domain, Boundary(domain), [U, U], laws=[SpeedLaw("linear"), SpeedLaw(HUMPS)])
    godunov, downstream = solver.transports(state, Boundary(domain).at(0.0))
    assert godunov.godunov and not downstream.godunov


def test_several_populations_share_the_bound_without_projection():
    """Two populations walking through each other (one law each), dense: the total stays <= 1 at cfl = 1."""
    domain = unit_square(16, exits=["left", "right"])
    rng = np.random.default_rng(2)
    total = rng.uniform(0.5, 1.0, domain.ncells)
    share = rng.uniform(0, 1, domain.ncells)
    rho0 = np.array([total * share, total * (1 - share)])
    velocities = [field(domain, "1", "0.3"), field(domain, "-1", "-0.2 + x")]
    worst, solver = run_steps(domain, velocities, [SpeedLaw("linear"), SpeedLaw(HUMPS)], rho0)
    assert not solver._projections and worst["projection"] == 0
    assert worst["max"] <= 1.0 + 1e-14 and worst["min"] >= 0.0
    assert worst["mass"] < 1e-13


def test_a_law_that_pushes_at_saturation_uses_the_projection(tmp_path):
    """f(1) = 1/2 > 0: people still push against the wall of cases/corridor-wall; the crowd saturates."""
    case = load_case(CASES / "corridor-wall", {"velocity.speed_law": "1 - 0.5 * rho", "time.end": 1.5})
    summary = Simulation(case).run().summary
    assert summary["projection_needed"]
    assert summary["active_set_iterations"]["steps_with_projection"] > 0
    assert summary["max_pressure_ever"] > 0 and summary["max_density_ever"] <= 1 + 1e-9
    assert summary["max_mass_error"] < 1e-13 and summary["min_density_ever"] >= 0
    assert summary["max_complementarity"] <= 1e-9 * summary["max_pressure_ever"]


def test_linear_law_summary_shows_no_projection():
    """f(1) = 0: the same scene never projects, and the crowd still fills the wall side up to rho = 1."""
    case = load_case(CASES / "corridor-wall", {"velocity.speed_law": "linear", "time.end": 3.0})
    summary = Simulation(case).run().summary
    assert not summary["projection_needed"]
    assert summary["active_set_iterations"] == {"mean": 0.0, "max": 0, "steps_with_projection": 0}
    assert summary["max_pressure_ever"] == 0.0
    assert 0.99 < summary["max_density_ever"] <= 1.0 + 1e-14


@pytest.mark.parametrize("law", ["linear", HUMPS])
def test_facet_fluxes_are_the_prediction(law):
    """The facet fluxes that measurement lines count (solver.facet_flux) are those of the LWR step, for two
    populations seeing their total: rho~_i - rho_i = -(divergence of the facet fluxes) / |K|, and the exit
    facets carry what step() reports as evacuated."""
    domain = unit_square(8, exits=["right"])
    rng = np.random.default_rng(3)
    rho0 = rng.uniform(0.0, 0.5, (2, domain.ncells))
    U, V = field(domain, "1", "0.3"), field(domain, "0.5", "-1")
    state = MacroState.initial(rho0, 1, ["a", "b"])
    solver = MacroSolver(domain, Boundary(domain), [U, V], laws=[SpeedLaw(law), SpeedLaw(law)])
    dt = solver.stable_dt(state)
    moved = solver.facet_flux(state, dt)
    k0, k1 = domain.f2t
    inner = k1 >= 0
    net = -np.bincount(k0, moved, domain.ncells) + np.bincount(k1[inner], moved[inner], domain.ncells)
    before = state.rho.copy()
    solver.step(state)
    np.testing.assert_allclose(state.rho.sum(axis=0) - before.sum(axis=0), net / domain.area, atol=1e-14)
    np.testing.assert_allclose(state.evacuated.sum(), moved[~inner].sum(), rtol=1e-12)
    # a line's facets (repeated, out of order) get exactly these fluxes, from their own flows alone
    some = np.array([5, 3, 40, 3, len(moved) - 1])
    np.testing.assert_array_equal(solver.facet_flux(MacroState.initial(rho0, 1, ["a", "b"]), dt, some), moved[some])
