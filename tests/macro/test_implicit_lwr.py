"""``scheme.transport = "implicit"`` with a speed law: the linearly implicit LWR transport
(transport/implicit.py, ImplicitLWRTransport; docs/model.md "Large steps with a speed law")."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.errors import InputError
from femcrowd.macro import MacroState
from femcrowd.macro.diagnostics import invariants
from femcrowd.macro.speed_law import SpeedLaw
from femcrowd.macro.transport import ImplicitLWRTransport, ImplicitUpwindTransport, flow_order
from femcrowd.macro.transport.flow_order import levels
from femcrowd.macro.velocity import FieldVelocity
from femcrowd.mesh import Boundary
from femcrowd.studies.extensions import lwr_riemann, observed_order

from ..support import CASES, unit_square

#: cases/bottleneck (Weidmann's law, push 0.2, a door capacity: the variant weidmann-push of
#: femcrowd/studies/recommended.py with the paper's walls) at large implicit steps
LARGE_STEPS = ["scheme.transport=implicit", "time.cfl_quantile=0.5", "time.cfl=4"]


def test_a_constant_speed_is_the_backward_euler_upwind_step():
    """f = 1 (an expression, so not the "constant" law that skips the LWR fluxes): the linearly implicit step, its
    evacuated mass and its facet fluxes are those of ImplicitUpwindTransport to round-off, at 20 x the CFL step."""
    domain = unit_square(8, exits=["right"])
    velocity = FieldVelocity(domain, Expression("1"), Expression("0.3"))
    exits = Boundary(domain).at(0.0)
    state = MacroState.initial(np.zeros((1, domain.ncells)), 1)
    normal = velocity.normal_on_facets(state, exits)
    lwr = ImplicitLWRTransport(domain, exits, normal, SpeedLaw("1 + 0 * rho"))
    upwind = ImplicitUpwindTransport(domain, exits, normal)
    rho = np.random.default_rng(2).uniform(0.0, 1.0, domain.ncells)
    dt = 20 * upwind.max_dt
    ours, theirs = lwr.step(rho, dt), upwind.step(rho, dt)
    np.testing.assert_allclose(ours.rho, theirs.rho, rtol=0, atol=1e-13)
    np.testing.assert_allclose(ours.outflow, theirs.outflow, rtol=1e-12)
    np.testing.assert_allclose(lwr.facet_flux(rho, dt), upwind.facet_flux(rho, dt), rtol=0, atol=1e-13)


def test_the_step_conserves_each_population_and_stays_positive():
    """Two populations, Weidmann's law of their total, compressive U, 30 x the explicit CFL step: each population's
    mass plus its evacuated mass is kept to round-off, rho~ >= 0, and the lagged speed blocks entry into a full
    cell (f(1) = 0: no flux into it)."""
    domain = unit_square(12, exits=["right"])
    rng = np.random.default_rng(5)
    rho = rng.uniform(0.0, 0.5, (2, domain.ncells))
    rho[:, 0] = 0.5   # one full cell (total 1)
    exits = Boundary(domain).at(0.0)
    state = MacroState.initial(rho, 1, ["a", "b"])
    total = rho.sum(axis=0)
    for i, (ux, uy) in enumerate([("(0.5 - x) * 4", "1"), ("1", "(0.5 - y) * 3")]):
        velocity = FieldVelocity(domain, Expression(ux), Expression(uy))
        scheme = ImplicitLWRTransport(domain, exits, velocity.normal_on_facets(state, exits), SpeedLaw("weidmann", 5.4))
        dt = 30 * scheme.max_dt
        step = scheme.step(rho[i], dt, total)
        assert step.rho.min() >= 0.0
        assert step.rho @ domain.area + step.outflow.sum() == pytest.approx(rho[i] @ domain.area, rel=1e-13)
        assert not np.any(scheme.flows(step.rho, total)[scheme.receiver == 0])


def test_weidmann_with_a_push_keeps_the_invariants_at_large_steps():
    """cases/bottleneck (Weidmann, push 0.2, door capacity) at cfl 4 on the median cell: the mass plus
    the evacuated is the initial mass to round-off, 0 <= rho <= 1 after the projection, p >= 0, p (1 - rho) = 0;
    the steps are larger than the explicit LWR scheme's."""
    keeps_the_invariants_at_large_steps(CASES / "bottleneck", LARGE_STEPS, ImplicitLWRTransport)


def keeps_the_invariants_at_large_steps(case_dir, overrides, transport):
    """20 steps of the case with `overrides`, its transport a `transport`: the mass plus the evacuated is the
    initial mass to round-off, 0 <= rho <= 1, p >= 0, p (1 - rho) = 0, and a step 4 times the explicit one; the
    transport."""
    model = Simulation(load_case(case_dir, overrides)).model
    solver, state, domain = model.solver, model.state, model.domain
    scheme = solver.transports(state, solver.boundary.at(0.0))[0]
    assert isinstance(scheme, transport) and solver.needs_projection
    m0 = state.rho @ domain.area
    largest = 0.0
    for _ in range(20):
        largest = max(largest, solver.step(state).dt)
        assert np.allclose(state.rho @ domain.area + state.evacuated.sum(axis=1), m0, rtol=0, atol=1e-12 * m0.sum())
        seen = invariants(domain, state)
        assert seen["min_density"] >= 0.0 and seen["max_density"] <= 1 + 1e-9 and seen["min_pressure"] >= 0.0
        assert seen["complementarity"] <= 1e-9 * max(seen["max_pressure"], 1.0)
    assert largest > 4 * scheme.max_dt and state.evacuated.sum() > 0
    return scheme


def colamd_step(scheme, rho, dt):
    """The system of a linearly implicit step (its matrix, right-hand side) and its solution by SuperLU with a
    COLAMD ordering, unclipped (the solve before the flow order)."""
    n = len(rho)
    speed = scheme.law(np.append(rho, 0.0)[scheme.receiver]) * scheme.rate
    inner = scheme.receiver < n
    rows = np.concatenate([np.arange(n), scheme.receiver[inner]])
    cols = np.concatenate([np.arange(n), scheme.sender[inner]])
    vals = np.concatenate([scheme.domain.area / dt + np.bincount(scheme.sender, speed, n), -speed[inner]])
    system, b = sp.csc_matrix((vals, (rows, cols)), shape=(n, n)), rho * scheme.domain.area / dt
    return system, b, spla.splu(system, permc_spec="COLAMD").solve(b)


@pytest.mark.parametrize("case, overrides", [("bottleneck", LARGE_STEPS),
                                             ("room", ["velocity.speed_law=weidmann", "velocity.walls=slip",
                                                       *LARGE_STEPS])])
def test_the_flow_order_solve_is_the_lu_solve(case, overrides):
    """40 steps at cfl 4 on the median cell: each step's system is an M-matrix (diagonal > 0, off-diagonal <= 0,
    column sums >= |K| / dt > 0), its solution in the block triangular order of the flow is the COLAMD LU's to
    1e-12, >= 0, and keeps the mass with the evacuated to 1e-13; the flow of both scenes has cycles (a facet
    crossed both ways)."""
    model = Simulation(load_case(CASES / case, overrides)).model
    solver, state, domain = model.solver, model.state, model.domain
    for _ in range(40):
        scheme = solver.transports(state, solver.boundary.at(state.t))[0]
        rho, dt = state.rho[0].copy(), solver.stable_dt(state)
        system, b, expected = colamd_step(scheme, rho, dt)
        off = system - sp.diags(system.diagonal())
        assert system.diagonal().min() > 0 and off.data.max(initial=0.0) <= 0.0
        assert np.all(np.asarray(system.sum(axis=0)).ravel() >= domain.area / dt * (1 - 1e-14))
        found = scheme.flow_order.solve(system.diagonal(), off[scheme.receiver[scheme.inner],
                                                               scheme.sender[scheme.inner]].A1, b)
        assert found.min() >= -1e-15
        np.testing.assert_allclose(found, expected, rtol=0, atol=1e-12)
        step = scheme.step(rho, dt)
        assert step.rho @ domain.area + step.outflow.sum() == pytest.approx(rho @ domain.area, rel=1e-13)
        solver.step(state)
    assert not scheme.flow_order.acyclic


def test_an_acyclic_flow_is_solved_by_substitution():
    """A uniform U on a square: the flow graph has no cycle, its levels grow along every flow, the ordered system is
    lower triangular and the step is the COLAMD LU's to 1e-13 at 20 x the CFL step."""
    domain = unit_square(16, exits=["right"])
    velocity = FieldVelocity(domain, Expression("1"), Expression("0.3"))
    exits = Boundary(domain).at(0.0)
    normal = velocity.normal_on_facets(MacroState.initial(np.zeros((1, domain.ncells)), 1), exits)
    scheme = ImplicitLWRTransport(domain, exits, normal, SpeedLaw("weidmann", 5.4))
    order = scheme.flow_order
    assert order.acyclic and order.small
    position = np.argsort(order.order)
    sender, receiver = scheme.sender[scheme.inner], scheme.receiver[scheme.inner]
    assert np.all(position[sender] < position[receiver])
    level = levels(domain.ncells, sender, receiver)
    assert np.all(level[sender] < level[receiver])
    rho = np.random.default_rng(3).uniform(0.0, 1.0, domain.ncells)
    dt = 20 * scheme.max_dt
    np.testing.assert_allclose(scheme.step(rho, dt).rho, colamd_step(scheme, rho, dt)[2], rtol=0, atol=1e-13)


def test_a_whirl_is_solved_by_lu_in_the_flow_order():
    """A rotating U with an exit: its cycles are longer than SMALL cells, the system is solved by LU in the flow
    order, and the step is the COLAMD LU's to 1e-13 at 20 x the CFL step; the same for the dense blocks' path
    (SMALL raised above the largest cycle)."""
    domain = unit_square(16, exits=["right"])
    velocity = FieldVelocity(domain, Expression("0.5 - y"), Expression("x - 0.5"))
    exits = Boundary(domain).at(0.0)
    normal = velocity.normal_on_facets(MacroState.initial(np.zeros((1, domain.ncells)), 1), exits)
    scheme = ImplicitLWRTransport(domain, exits, normal, SpeedLaw("weidmann", 5.4))
    assert not scheme.flow_order.small
    rho = np.random.default_rng(4).uniform(0.0, 1.0, domain.ncells)
    dt = 20 * scheme.max_dt
    expected = colamd_step(scheme, rho, dt)[2]
    np.testing.assert_allclose(scheme.step(rho, dt).rho, expected, rtol=0, atol=1e-13)
    sender, receiver = scheme.sender[scheme.inner], scheme.receiver[scheme.inner]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(flow_order, "SMALL", domain.ncells)
        scheme.flow_order = flow_order.FlowOrder(sender, receiver, domain.ncells)
    assert scheme.flow_order.small
    np.testing.assert_allclose(scheme.step(rho, dt).rho, expected, rtol=0, atol=1e-13)


@pytest.mark.parametrize("direct", [True, False], ids=["gstrs", "public-wrapper"])
def test_the_substitution_is_scipys_triangular_solve_bit_for_bit(direct, monkeypatch):
    """The flow order's substitution on its fixed pattern (gstrs called directly, or the public wrapper where
    scipy's private module is missing; the products D^{-1} N found once)
    gives spsolve_triangular's solution of (I + D^{-1} N) x = D^{-1} b bit for bit, D^{-1} N and D^{-1} b built
    by scipy's sparse products: blocks of one to three cells, flows from earlier blocks, some into every cell of
    a block from one sender (sums of two and three products, in the same order), random values."""
    rng = np.random.default_rng(7)
    size = rng.choice([1, 2, 3], 200, p=[0.5, 0.3, 0.2])
    first = np.concatenate([[0], np.cumsum(size)[:-1]])
    n = int(size.sum())
    cells = np.arange(n)
    rows = np.concatenate([np.repeat(f + np.arange(s), s) for f, s in zip(first, size)])
    cols = np.concatenate([np.tile(f + np.arange(s), s) for f, s in zip(first, size)])
    inverse = rng.uniform(0.1, 2.0, len(rows))
    receiver = rng.choice(cells[cells >= 2], 400)
    sender = (rng.uniform(size=400) * first[np.searchsorted(first, receiver, side="right") - 1]).astype(int)
    fed = np.flatnonzero((size > 1) & (first > 0))[:30]   # every cell of 30 blocks fed by cell 0
    into = np.concatenate([first[k] + np.arange(size[k]) for k in fed])
    receiver, sender = np.concatenate([receiver, into]), np.concatenate([sender, 0 * into])
    key = np.unique(receiver * n + sender)
    receiver, sender = key // n, key % n
    flow = -rng.uniform(0.0, 1.0, len(key))
    b = rng.uniform(0.0, 1.0, n)
    if not direct:
        monkeypatch.setattr(flow_order, "gstrs", None)
    found = flow_order._Substitution(rows, cols, receiver, sender, n).solve(inverse, flow, b)
    d_inverse = sp.csr_matrix((inverse, (rows, cols)), shape=(n, n))
    scaled = d_inverse @ sp.csr_matrix((flow, (receiver, sender)), shape=(n, n)) + sp.identity(n, format="csr")
    expected = spla.spsolve_triangular(scaled, d_inverse @ b, lower=True, unit_diagonal=True)
    assert np.array_equal(found, expected)
    assert np.count_nonzero(size[fed] == 3) > 5   # entries summed from three products


def test_levels_refuse_a_cycle():
    """levels() is for acyclic graphs: a 3-cycle is an error, not a wrong order."""
    with pytest.raises(ValueError, match="cycle"):
        levels(4, np.array([0, 1, 2, 3]), np.array([1, 2, 0, 0]))


def test_the_rarefaction_converges_at_small_steps():
    """cases/lwr-fan (linear law) at cfl 0.5 on three meshes: L1 error and the fan's mid-point shrink at every
    refinement; the projection keeps rho <= 1. Observed on the finer pair: L1 0.73, mid-point 0.55 (the explicit
    scheme: 0.82, 0.99; the lagged speed's diffusion slows the fan's middle)."""
    rows = lwr_riemann(3, "fan", {"scheme.transport": "implicit", "time.cfl": 0.5})
    for row in rows:
        assert row["mass_error"] < 1e-12 and row["min_density"] >= 0.0 and row["max_density"] <= 1 + 1e-9
    for metric in ("l1", "position_error"):
        errors = np.abs([row[metric] for row in rows])
        assert np.all(np.diff(errors) < 0), (metric, errors)
    assert observed_order(rows, "l1") > 0.5, rows
    assert observed_order(rows, "position_error") > 0.45, rows


def test_a_transport_without_a_speed_law_scheme_is_refused():
    """compressive has no speed-law scheme: the one-line error names the key and the transports that have one."""
    with pytest.raises(InputError, match="use one of 'upwind', 'muscl', 'implicit', 'implicit-godunov'"):
        Simulation(load_case(CASES / "bottleneck", ["scheme.transport=compressive", "time.cfl=0.5"]))
