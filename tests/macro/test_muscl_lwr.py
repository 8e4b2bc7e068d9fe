"""muscl with a speed law (macro/transport/muscl_lwr.py): Godunov's flux between limited linear reconstructions,
SSP-RK2, at cfl 0.5 of the LWR transport's step. The exact Riemann problems of the linear law (cases/lwr-shock,
lwr-fan) against the order-0 LWR fluxes on the same meshes; mass per population, bounds, the projection."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.errors import InputError
from femcrowd.macro import MacroSolver, MacroState
from femcrowd.macro.speed_law import SpeedLaw
from femcrowd.macro.transport import MUSCLLWRTransport, MUSCLTransport
from femcrowd.mesh import Boundary
from femcrowd.studies.extensions import lwr_riemann, observed_order

from ..support import CASES, unit_square
from .test_extensions_exact import check_invariants
from .test_lwr import HUMPS, field

SECOND = {"scheme.transport": "muscl", "time.cfl": 0.5}


@pytest.mark.parametrize("kind, order", [("shock", 0.9), ("fan", 1.2)])
def test_riemann_problems_converge_faster_than_order_0(kind, order):
    """Three meshes each: the L1 error at t = 1 is under 0.6 of the order-0 fluxes' on every mesh, its observed
    order on the finer pair is above `order` and above order 0's (0.67 shock, 0.82 fan; muscl 0.96, 1.32), the
    shock (the fan's middle) still ~ h; mass, 0 <= rho <= 1, and the crowd never saturates (no active set)."""
    first, second = lwr_riemann(3, kind, {"time.cfl": 0.5}), lwr_riemann(3, kind, SECOND)
    check_invariants(second)
    assert all(row["projection_steps"] == 0 for row in second)
    assert [row["steps"] for row in second] == [row["steps"] for row in first]   # the same step
    assert all(s["l1"] < 0.6 * f["l1"] for s, f in zip(second, first)), (first, second)
    assert observed_order(second, "l1") > max(order, observed_order(first, "l1") + 0.25), (first, second)
    assert observed_order(second, "position_error") > 0.8, second


def run(domain, velocities, laws, rho0, steps):
    """muscl steps of a MacroSolver at cfl 0.5; the worst mass balance per population (relative), smallest
    population, largest total, smallest pressure and complementarity over the steps."""
    state = MacroState.initial(rho0, len(domain.exit_names), [f"p{i}" for i in range(len(rho0))])
    solver = MacroSolver(domain, Boundary(domain), velocities, transport="muscl", cfl=0.5, laws=laws)
    mass0 = rho0 @ domain.area
    worst = {"mass": 0.0, "min": 0.0, "max": 0.0, "p": 0.0, "complementarity": 0.0}
    for _ in range(steps):
        solver.step(state)
        balance = state.rho @ domain.area + state.evacuated.sum(axis=1) - mass0
        worst["mass"] = max(worst["mass"], np.abs(balance).max() / mass0.max())
        worst["min"] = min(worst["min"], state.rho.min())
        worst["max"] = max(worst["max"], state.density.max())
        worst["p"] = min(worst["p"], state.p.min())
        worst["complementarity"] = max(worst["complementarity"], np.abs(state.p * (1 - state.density)).max())
    return worst, solver, state


@pytest.mark.parametrize("laws", [("linear", HUMPS), ("1 - 0.7 * rho", None)])
def test_several_populations_keep_mass_and_bounds(laws):
    """Two populations walking through each other on dense random data (one with f(1) = 0 and one whose g has two
    humps; or a law that pushes at saturation and f = 1): each population's mass (with what left) to 1e-13,
    rho_i >= 0, the total <= 1, p >= 0 and p (1 - rho) = 0 after the projection, which muscl always builds."""
    domain = unit_square(16, exits=["left", "right"])
    rng = np.random.default_rng(2)
    total, share = rng.uniform(0.5, 1.0, domain.ncells), rng.uniform(0, 1, domain.ncells)
    rho0 = np.array([total * share, total * (1 - share)])
    velocities = [field(domain, "1", "0.3"), field(domain, "-1", "-0.2 + x")]
    worst, solver, state = run(domain, velocities, [law and SpeedLaw(law) for law in laws], rho0, 60)
    assert solver.needs_projection and solver.together
    assert all(isinstance(s, MUSCLLWRTransport) for s in solver.transports(state, Boundary(domain).at(0.0)))
    assert worst["mass"] < 1e-13 and worst["min"] >= 0.0 and worst["max"] <= 1 + 1e-9
    assert worst["p"] >= 0.0 and worst["complementarity"] <= 1e-9
    assert state.evacuated[0, 1] > 0 and state.evacuated[1, 0] > 0   # through the right and the left exit


def test_f_equal_1_is_the_muscl_step():
    """f = 1 as an expression (Godunov's flux q min(D(r_K), S(r_L)) = q r_K for r <= r* = 1): the step of the LWR scheme
    is muscl's upwind step with the same facet values, to round-off (the stages' sums in another order)."""
    domain = unit_square(16, exits=["right"])
    rho = np.random.default_rng(4).uniform(0.0, 0.5, domain.ncells)   # the first stage's stays < 1: D(r) = r
    U = field(domain, "1", "0.5 - y")
    exits = Boundary(domain).at(0.0)
    normal = U.normal_on_facets(MacroState.initial(rho[None], 1), exits)
    lwr, upwind = MUSCLLWRTransport(domain, exits, normal, SpeedLaw("1 + 0 * rho")), MUSCLTransport(domain, exits,
                                                                                                     normal)
    dt = 0.5 * upwind.max_dt
    mine, theirs = lwr.step(rho, dt), upwind.step(rho, dt)
    np.testing.assert_allclose(mine.rho, theirs.rho, rtol=0, atol=1e-14)
    np.testing.assert_allclose(mine.outflow, theirs.outflow, rtol=1e-13)
    np.testing.assert_allclose(lwr.facet_flux(rho, dt), upwind.facet_flux(rho, dt), rtol=0, atol=1e-15)


@pytest.mark.parametrize("law", ["linear", HUMPS])
def test_facet_fluxes_are_the_prediction(law):
    """The facet fluxes that measurement lines count (solver.facet_flux: the mean of the two stages', both
    populations seeing each stage's total) give the step: rho - rho0 = -(divergence) / |K| (sparse crowds, no
    projection acts); the exit facets carry what left, the walls nothing."""
    domain = unit_square(8, exits=["right"])
    rho0 = np.random.default_rng(3).uniform(0.0, 0.5, (2, domain.ncells))
    state = MacroState.initial(rho0, 1, ["a", "b"])
    solver = MacroSolver(domain, Boundary(domain), [field(domain, "1", "0.3"), field(domain, "0.5", "-1")],
                         transport="muscl", laws=[SpeedLaw(law), SpeedLaw(law)])
    dt = solver.stable_dt(state)
    moved = solver.facet_flux(state, dt)
    k0, k1 = domain.f2t
    inner = k1 >= 0
    net = -np.bincount(k0, moved, domain.ncells) + np.bincount(k1[inner], moved[inner], domain.ncells)
    solver.step(state)
    np.testing.assert_allclose(state.rho.sum(axis=0) - rho0.sum(axis=0), net / domain.area, atol=1e-14)
    np.testing.assert_allclose(state.evacuated.sum(), moved[~inner].sum(), rtol=1e-12)
    walls = ~inner & ~np.isin(np.arange(len(moved)), domain.groups["right"])
    assert np.all(moved[walls] == 0.0) and moved[~inner].sum() > 0


def test_constant_law_keeps_muscl_bit_for_bit():
    """Without a speed law (or the "constant" one) muscl is the upwind-flux scheme it was, each population alone."""
    domain = unit_square(8, exits=["right"])
    U = field(domain, "1", "0")
    solver = MacroSolver(domain, Boundary(domain), [U, U], transport="muscl", laws=[SpeedLaw("constant"), None])
    state = MacroState.initial(np.zeros((2, domain.ncells)), 1)
    assert not solver.together
    assert all(type(s) is MUSCLTransport for s in solver.transports(state, Boundary(domain).at(0.0)))


def test_a_case_with_a_speed_law_runs_muscl_at_its_cfl():
    """cases/bottleneck (Weidmann's law, push 0.2, a capacity on the exit) with muscl, refused before: 2 s of it,
    mass to 1e-12, 0 <= rho <= rho_max, p >= 0; cfl 1 is refused (muscl's limit is 0.5)."""
    summary = Simulation(load_case(CASES / "bottleneck", ["scheme.transport=muscl", "time.cfl=0.5",
                                                          "time.end=2"])).run().summary
    assert summary["max_mass_error"] < 1e-12 and summary["min_density_ever"] >= 0
    assert summary["max_density_ever"] <= 5.4 * (1 + 1e-9) and summary["min_pressure_ever"] >= 0
    with pytest.raises(InputError, match="time.cfl"):
        Simulation(load_case(CASES / "bottleneck", ["scheme.transport=muscl", "time.cfl=1"]))
