"""``scheme.transport = "implicit-godunov"`` (transport/implicit.py, ImplicitGodunovTransport; docs/model.md "Steps by
accuracy"): the linearly implicit step with the rates of the explicit LWR fluxes frozen at the step's start. At
rho~ = rho^n its fluxes are Godunov's; each population's mass is kept and rho~ >= 0 at any step; it tends to the
explicit scheme at first order; a capped interior door passes exactly its capacity."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.macro import MacroState
from femcrowd.macro.diagnostics import invariants
from femcrowd.macro.speed_law import SpeedLaw
from femcrowd.macro.transport import ImplicitGodunovTransport, ImplicitLWRTransport, LWRTransport
from femcrowd.macro.velocity import FieldVelocity
from femcrowd.mesh import Boundary
from femcrowd.studies.recommended import MACRO

from ..support import CASES, unit_square
from .test_implicit_capacity import UNIMODAL, rooms
from .test_implicit_lwr import keeps_the_invariants_at_large_steps

#: the desired velocities (U_x, U_y) of the two populations of two_populations: compressive, then along x
FIELDS = [("(0.5 - x) * 4", "1"), ("1", "(0.5 - y) * 3")]


def two_populations(n=12):
    """Two populations on the unit square (exit right), Predtechenskii and Milinskii's law of their total (unimodal),
    one saturated cell and one empty cell; their schemes (compressive U for the first), the densities, the total."""
    domain = unit_square(n, exits=["right"])
    rng = np.random.default_rng(5)
    rho = rng.uniform(0.0, 0.5, (2, domain.ncells))
    rho[:, 0] = 0.5   # a full cell (total 1)
    rho[:, 1] = 0.0   # an empty one
    exits = Boundary(domain).at(0.0)
    state = MacroState.initial(rho, 1, ["a", "b"])
    law = SpeedLaw("predtechenskii", 5.4)
    assert law.unimodal and law.saturates
    schemes = []
    for ux, uy in FIELDS:
        velocity = FieldVelocity(domain, Expression(ux), Expression(uy))
        normal = velocity.normal_on_facets(state, exits)
        schemes.append((ImplicitGodunovTransport(domain, exits, normal, law), LWRTransport(domain, exits, normal, law)))
    return domain, schemes, rho, rho.sum(axis=0)


def test_the_frozen_rates_carry_the_explicit_godunov_flux():
    """At rho~ = rho^n each flow carries what the explicit scheme's does, min(D(total_K), S(total_L)) times the
    population's share, to round-off; every rate is >= 0, the empty sender's is q_e f(0) = q_e; the rates of the
    flux rho_K f(rho_L) (ImplicitLWRTransport) differ."""
    domain, schemes, rho, total = two_populations()
    for i, (implicit, explicit) in enumerate(schemes):
        speeds = implicit.speeds(rho[i], total)
        frozen = speeds * rho[i][implicit.sender]
        np.testing.assert_allclose(frozen, explicit.flows(rho[i], total), rtol=1e-14, atol=1e-16)
        empty = implicit.sender == 1
        assert np.all(speeds >= 0) and np.any(empty)
        np.testing.assert_array_equal(speeds[empty], implicit.rate[empty])
        lagged = ImplicitLWRTransport.speeds(implicit, rho[i], total) * rho[i][implicit.sender]
        assert np.abs(lagged - frozen).max() > 0.1 * np.abs(frozen).max()


def test_the_law_is_taken_once_per_cell_bit_for_bit():
    """The speed law evaluated on the cells and gathered to the flows (the flows outnumber the cells, lwr.law_at)
    gives the numbers of the law evaluated on each flow's own densities, bit for bit: the rates of both implicit
    schemes, the explicit fluxes (Godunov's, and rho_K f(rho_L) of a law with two humps) of all flows and of a few
    (a measurement line's); densities above 1, exactly 0, exactly r*, and the empty outside of the exit flows (the
    second population's)."""
    domain, schemes, rho, total = two_populations()
    total[2], total[3] = 1.3, schemes[0][0].law.r_star
    assert np.any(schemes[1][0].receiver == domain.ncells)
    humps = SpeedLaw("where(rho < 0.3, 1, where(rho < 0.4, 1 - 8 * (rho - 0.3), where(rho < 0.9, 0.2, 2 * (1 - rho))))")
    seen = np.append(total, 0.0)
    exits = Boundary(domain).at(0.0)
    for (implicit, explicit), (ux, uy) in zip(schemes, FIELDS):
        law, sender, receiver = implicit.law, seen[implicit.sender], seen[implicit.receiver]
        assert len(implicit.sender) > len(seen)
        supply = law.supply(receiver)
        limit = np.where(supply > 0, law(np.zeros(1)), 0.0)
        godunov = np.divide(np.minimum(law.demand(sender), supply), sender, out=limit, where=sender > 0)
        assert np.array_equal(implicit.speeds(rho[0], total), godunov * implicit.rate)
        lagged = ImplicitLWRTransport.speeds(implicit, rho[0], total)
        assert np.array_equal(lagged, law(receiver) * implicit.rate)
        share = np.where(sender > 0, rho[0][implicit.sender] / np.where(sender > 0, sender, 1.0), 0.0)
        assert np.array_equal(explicit.flows(rho[0], total), np.minimum(law.demand(sender), supply) * share
                              * explicit.rate)
        few = np.arange(5)
        assert np.array_equal(explicit.flows(rho[0], total, few), explicit.flows(rho[0], total)[few])
        normal = FieldVelocity(domain, Expression(ux), Expression(uy)).normal_on_facets(MacroState.initial(
            rho, 1, ["a", "b"]), exits)
        other = LWRTransport(domain, exits, normal, humps)
        assert not other.godunov and np.array_equal(other.sender, explicit.sender)
        assert np.array_equal(other.flows(total), sender * humps(receiver) * explicit.rate)


def test_each_population_keeps_its_mass_and_stays_positive_at_large_steps():
    """30 and 100 x the explicit CFL step: rho~ >= 0, each population's mass plus what left through the exit is its
    mass before to round-off."""
    domain, schemes, rho, total = two_populations()
    for i, (implicit, _) in enumerate(schemes):
        for cfl in (30, 100):
            step = implicit.step(rho[i], cfl * implicit.max_dt, total)
            assert step.rho.min() >= 0.0
            assert step.rho @ domain.area + step.outflow.sum() == pytest.approx(rho[i] @ domain.area, rel=1e-13)


def test_the_recommended_settings_keep_the_invariants_at_cfl_4():
    """cases/bottleneck with the recommended settings (Predtechenskii and Milinskii's law, slip walls) and
    implicit-godunov at cfl 4 on the median cell: the mass plus the evacuated is the initial mass to round-off,
    0 <= rho <= 1, p >= 0, p (1 - rho) = 0, and the steps are larger than the explicit step's."""
    settings = {**MACRO, "velocity.push": 0.0, "scheme.transport": "implicit-godunov", "time.cfl_quantile": 0.5,
                "time.cfl": 4.0}
    assert keeps_the_invariants_at_large_steps(CASES / "bottleneck", settings, ImplicitGodunovTransport).godunov


def test_within_the_cfl_step_it_is_the_explicit_step(tmp_path):
    """The channel of a capped door with a unimodal law at cfl 1 and 1/2 of the smallest cell's step: every omega is
    0, so after 1 s the density is the explicit LWR fluxes' (Godunov's, the door's cut after the step) to 1e-13;
    the lagged-speed implicit step (its flux not Godunov's, backward Euler) is more than 1e-3 away."""
    for cfl in (1.0, 0.5):
        rho = {}
        for transport in ("upwind", "implicit", "implicit-godunov"):
            directory = tmp_path / f"{transport}-{cfl}"
            directory.mkdir()
            model = rooms(directory, transport=transport, cfl=cfl, quantile=0, end=1.0, law=UNIMODAL)
            while model.state.t < 1.0 - 1e-12:
                model.solver.step(model.state, 1.0)
            rho[transport] = model.state.density
        area = model.domain.area
        assert area @ np.abs(rho["implicit-godunov"] - rho["upwind"]) <= 1e-13
        assert area @ np.abs(rho["implicit"] - rho["upwind"]) > 1e-3


def test_the_implicit_share_keeps_the_explicit_part_positive():
    """At 0.5, 3 and 30 x the explicit CFL step: omega_K = 0 where tau out_K <= |K|, in [0, 1) elsewhere, and the
    explicit part's coefficient |K| / tau - (1 - omega_K) out_K is >= 0 in every cell (0 where omega > 0)."""
    domain, schemes, rho, total = two_populations()
    for i, (implicit, _) in enumerate(schemes):
        speed = implicit.speeds(rho[i], total)
        out = np.bincount(implicit.sender, speed, domain.ncells)
        for cfl in (0.5, 3, 30):
            dt = cfl * implicit.max_dt
            share = implicit.share(dt, speed)
            within = dt * out <= domain.area
            assert np.all(share[within] == 0) and np.all((share >= 0) & (share < 1))
            coefficient = domain.area / dt - (1 - share) * out
            assert coefficient.min() >= -1e-12 * (domain.area / dt).max()
            np.testing.assert_allclose(coefficient[~within], 0.0, atol=1e-12 * (domain.area / dt).max())
        assert np.any(~within)


def test_measurement_lines_count_the_mass_the_step_moves(tmp_path):
    """Two populations at cfl 4 on the median cell: across the facets around the cells beyond x = 1.5 the
    prediction's facet fluxes (solver.facet_flux, what measurement lines count) plus the correction's are the
    mass those cells lost in the step, to round-off."""
    model = rooms(tmp_path, transport="implicit-godunov", cfl=4, populations=2, law=UNIMODAL)
    solver, state, domain = model.solver, model.state, model.domain
    inside = domain.centroid[:, 0] > 1.5
    k0, k1 = domain.f2t
    facets = np.flatnonzero(domain.interior & (inside[k0] != inside[np.maximum(k1, 0)]))
    sign = np.where(inside[k0[facets]], 1.0, -1.0)   # out of the cells beyond x = 1.5
    lost = 0.0
    for _ in range(10):
        exits = solver.boundary.at(state.t)
        dt = solver.stable_dt(state)
        before = state.density[inside] @ domain.area[inside]
        moved = solver.facet_flux(state, dt, facets)
        info = solver.step(state)
        assert info.dt == dt
        moved = moved + info.flux.facet_flux(domain, exits, facets)
        change = before - state.density[inside] @ domain.area[inside]
        assert sign @ moved == pytest.approx(change, rel=0, abs=1e-13)
        lost += change
    assert lost > 0.05


def test_the_papers_model_takes_the_scheme_too():
    """No speed law (f = 1) on cases/bottleneck: implicit-godunov is ImplicitGodunovTransport with f = 1, at a fixed
    step within the CFL step the explicit upwind step (to 1e-8 after 30 steps: the law's r* is 1 to 1e-9), and at
    cfl 8 on the median cell it keeps the mass and the bounds."""
    paper = ["velocity.speed_law=constant", "velocity.push=0"]
    upwind = Simulation(load_case(CASES / "bottleneck", paper + ["scheme.transport=upwind"])).model
    dt = 0.9 * upwind.solver.stable_dt(upwind.state) / 0.5   # 0.9 of the CFL step (cfl 0.5 by default)
    fixed = [f"time.dt={dt!r}"]
    upwind = Simulation(load_case(CASES / "bottleneck", paper + fixed)).model
    ours = Simulation(load_case(CASES / "bottleneck", paper + fixed + ["scheme.transport=implicit-godunov"])).model
    assert isinstance(ours.solver.transports(ours.state, ours.solver.boundary.at(0.0))[0], ImplicitGodunovTransport)
    for _ in range(30):
        assert upwind.solver.step(upwind.state).dt == ours.solver.step(ours.state).dt == dt
    np.testing.assert_allclose(ours.state.rho, upwind.state.rho, rtol=0, atol=1e-8)
    large = Simulation(load_case(CASES / "bottleneck", paper + ["scheme.transport=implicit-godunov",
                                                                 "time.cfl_quantile=0.5", "time.cfl=8"])).model
    m0 = large.state.rho @ large.domain.area
    for _ in range(10):
        large.solver.step(large.state)
        r = invariants(large.domain, large.state)
        assert abs(r["mass"] + r["evacuated"] - m0.sum()) <= 1e-12 * m0.sum()
        assert r["min_density"] >= 0 and r["max_density"] <= 1 + 1e-9 and r["min_pressure"] >= 0


def test_beyond_the_cfl_step_the_error_falls_at_first_order(tmp_path):
    """The same channel at 20, 10 and 5 times the smallest cell's step: the L1 distance at t = 1 to the explicit
    step at a quarter of it (the small-step limit) falls at least as fast as the step (ratios 1.8 to 3.5: the
    cell-wise theta's diffusion |1 - c| |v| h / 2 shrinks faster than c), and is below the lagged-speed implicit
    step's at every step."""
    def density(transport, cfl):
        directory = tmp_path / f"{transport}-{cfl}"
        directory.mkdir()
        model = rooms(directory, transport=transport, cfl=cfl, quantile=0, end=1.0, law=UNIMODAL)
        while model.state.t < 1.0 - 1e-12:
            model.solver.step(model.state, 1.0)
        return model.state.density, model.domain.area

    limit, area = density("upwind", 0.25)
    distance = {t: [area @ np.abs(density(t, cfl)[0] - limit) for cfl in (20, 10, 5)]
                for t in ("implicit-godunov", "implicit")}
    godunov = np.array(distance["implicit-godunov"])
    ratios = godunov[:-1] / godunov[1:]
    assert np.all((ratios > 1.8) & (ratios < 3.5)), (distance, ratios)
    assert np.all(godunov < distance["implicit"]), distance
