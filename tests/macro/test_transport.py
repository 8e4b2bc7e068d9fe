"""The transport schemes: the invariants of the higher-order options along runs, their CFL limits."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.errors import InputError
from femcrowd.macro import MacroState
from femcrowd.macro.transport import ImplicitUpwindTransport, UpwindTransport
from femcrowd.macro.velocity import ExitsVelocity
from femcrowd.mesh import Boundary

from ..support import CASES


@pytest.mark.parametrize("transport", ["muscl", "compressive"])
@pytest.mark.parametrize("name, steps", [("radial", 40), ("room", 60), ("saturated-exit", 40)])
def test_higher_order_transport_keeps_the_invariants(name, steps, transport):
    """[scheme] transport = muscl / compressive: mass to 1e-10 (with the evacuated mass),
    0 <= rho <= 1, p >= 0 at every step."""
    model = Simulation(load_case(CASES / name, [f"scheme.transport={transport}"])).model
    solver, state, area = model.solver, model.state, model.domain.area
    m0 = model.initial_mass
    for _ in range(steps):
        solver.step(state)
        assert abs(area @ state.density + state.evacuated.sum() - m0) <= 1e-10 * m0
        assert state.rho.min() >= 0.0 and state.rho.max() <= 1 + 1e-9
        assert state.p.min() >= 0.0
        assert np.all(np.isfinite(state.rho))
    # the predictor alone is non-negative at the CFL limit of order 0
    transport = solver.transports(state, solver.boundary.at(state.t))[0]
    rho_tilde = transport.step(state.density, transport.max_dt).rho
    assert rho_tilde.min() >= 0.0


@pytest.mark.parametrize("transport", ["muscl", "compressive"])
def test_higher_order_transports_refuse_a_cfl_above_their_limit(transport):
    with pytest.raises(InputError, match="time.cfl"):
        Simulation(load_case(CASES / "radial", [f"scheme.transport={transport}", "time.cfl=0.8"]))


@pytest.mark.parametrize("cfl", [1.0, 5.0, 20.0])
def test_implicit_transport_keeps_the_invariants_at_large_steps(cfl):
    """Backward-Euler upwind beyond the explicit CFL limit: mass (with what left) to 1e-12 at every step,
    0 <= rho <= 1, p >= 0 after the projection."""
    case = load_case(CASES / "room", ["scheme.transport=implicit", f"time.cfl={cfl}"])
    model = Simulation(case).model
    solver, state, area = model.solver, model.state, model.domain.area
    m0 = model.initial_mass
    for _ in range(30):
        solver.step(state)
        assert abs(area @ state.density + state.evacuated.sum() - m0) <= 1e-12 * m0
        assert state.rho.min() >= 0.0 and state.rho.max() <= 1 + 1e-9 and state.p.min() >= 0.0
    assert state.evacuated.sum() > 0


def test_implicit_transport_is_consistent_and_its_ordered_solve_exact(room_domain):
    """One implicit step differs from an explicit one by O(dt^2); solved in the order of the distance
    to the exits (little fill) it equals the solve in a fill-reducing order."""
    exits = Boundary(room_domain).at(0.0)
    velocity = ExitsVelocity(room_domain, Expression("1"))
    normal = velocity.normal_on_facets(MacroState.initial(np.zeros((1, room_domain.ncells)), 1), exits)
    rho = np.clip(1.2 - 0.15 * np.hypot(*(room_domain.centroid - [8, 3]).T), 0, 1)
    ordered = ImplicitUpwindTransport(room_domain, exits, normal, velocity.potential(exits))
    plain = ImplicitUpwindTransport(room_domain, exits, normal)
    explicit = UpwindTransport(room_domain, exits, normal)
    differences = []
    for dt in (0.5 * explicit.max_dt, 0.25 * explicit.max_dt):
        a, out_a, _ = ordered.step(rho, dt)
        b, out_b, _ = plain.step(rho, dt)
        assert np.abs(a - b).max() <= 1e-12 and np.allclose(out_a, out_b, rtol=1e-12, atol=0)
        differences.append(room_domain.area @ np.abs(a - explicit.step(rho, dt)[0]))
    assert 3.5 < differences[0] / differences[1] < 4.5  # O(dt^2) per step
