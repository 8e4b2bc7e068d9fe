"""The transport schemes: the invariants of the higher-order options along runs, their CFL limits."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.errors import InputError

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
    rho_tilde, _ = transport.step(state.density, transport.max_dt)
    assert rho_tilde.min() >= 0.0


@pytest.mark.parametrize("transport", ["muscl", "compressive"])
def test_higher_order_transports_refuse_a_cfl_above_their_limit(transport):
    with pytest.raises(InputError, match="time.cfl"):
        Simulation(load_case(CASES / "radial", [f"scheme.transport={transport}", "time.cfl=0.8"]))
