"""The correction of several populations (macro/populations.py): the implicit upwind split of the pressure
flux keeps every population >= 0, conserves each one, and sums to the projected total."""

import numpy as np

from femcrowd import Simulation, load_case
from femcrowd.macro.populations import split_correction
from femcrowd.mesh import Boundary

from ..support import CASES, Projector, unit_square


def explicit_split(domain, exits, flux, rho_tilde):
    """The split by the fractions of the upwind cell's prediction rho~ (what the implicit split avoids)."""
    moved = flux.facet_flux(domain, exits)
    k0, k1 = domain.f2t
    rho = rho_tilde.copy()
    for f in np.flatnonzero(moved):
        sender, receiver = (k0[f], k1[f]) if moved[f] > 0 else (k1[f], k0[f])
        share = rho_tilde[:, sender] / rho_tilde[:, sender].sum()
        rho[:, sender] -= abs(moved[f]) * share / domain.area[sender]
        if receiver >= 0:
            rho[:, receiver] += abs(moved[f]) * share / domain.area[receiver]
    return rho


def stream_through_a_saturated_zone():
    """Population A piled up at 3 on the left, population B at rest (rho~ = 1) between A and the exit on the
    right: the pressure pushes A's excess out through B's cells, more mass than each of them holds."""
    domain = unit_square(16, exits=["right"])
    exits = Boundary(domain).at(0.0)
    x = domain.centroid[:, 0]
    rho_tilde = np.array([np.where(x < 0.25, 3.0, 0.0), np.where(x < 0.25, 0.0, 1.0)])
    return domain, exits, rho_tilde


def test_the_implicit_split_is_positive_and_conservative():
    domain, exits, rho_tilde = stream_through_a_saturated_zone()
    project = Projector(domain)
    total, phi, _ = project(rho_tilde.sum(axis=0))
    flux, _ = project.projection(rho_tilde.sum(axis=0))
    rho, pushed_out = split_correction(domain, exits, flux, rho_tilde, total)
    assert rho.min() >= 0.0
    # the projected total, to the round-off of the facet fluxes T_e (phi_K - phi_L) divided by |K|
    assert np.abs(rho.sum(axis=0) - total).max() < 1e-10
    mass = rho_tilde @ domain.area
    assert np.allclose(rho @ domain.area + pushed_out.sum(axis=1), mass, rtol=1e-14, atol=0)
    assert np.isclose(pushed_out.sum(), 0.5, rtol=1e-12)                        # the excess 3 x 1/4 - 1/4 left
    assert pushed_out[0].sum() > 0.05 and pushed_out[1].sum() > 0.05           # A streamed out, B pushed out too
    # the explicit split of the same fluxes makes B negative where A's stream crosses B's cells
    assert explicit_split(domain, exits, flux, rho_tilde)[1].min() < -0.1


def test_one_population_is_the_plain_correction():
    domain, exits, rho_tilde = stream_through_a_saturated_zone()
    project = Projector(domain)
    flux, _ = project.projection(rho_tilde[0])
    total = flux.apply(rho_tilde[0], domain.area)
    rho, pushed_out = split_correction(domain, exits, flux, rho_tilde[:1], total)
    assert np.abs(rho[0] - total).max() < 1e-10
    assert np.isclose(pushed_out.sum(), rho_tilde[0] @ domain.area - total @ domain.area, rtol=1e-13)


def test_colours_of_one_crowd_are_split_in_proportion():
    """Two populations mixed in the same proportion everywhere stay in that proportion (y_i = constant)."""
    domain, exits, rho_tilde = stream_through_a_saturated_zone()
    total_tilde = rho_tilde.sum(axis=0)
    mixed = np.array([0.3 * total_tilde, 0.7 * total_tilde])
    project = Projector(domain)
    flux, _ = project.projection(total_tilde)
    total = flux.apply(total_tilde, domain.area)
    rho, _ = split_correction(domain, exits, flux, mixed, total)
    assert np.allclose(rho[0], 0.3 * total, rtol=0, atol=1e-10)
    assert np.allclose(rho[1], 0.7 * total, rtol=0, atol=1e-10)


def test_populations_behind_capped_exits():
    """Two populations, each to its own exit, both exits with a capacity (RiMEA test 10's scene): the flux across
    a capped exit facet is 0 up to round-off, of either sign, and is no inflow; every population keeps its mass."""
    case = load_case(CASES / "rimea" / "test10-escape-routes", ["boundary.capacity={main=1.9, secondary=1.9}",
                                                               "time.end=3"])
    result = Simulation(case).run(None, quiet=True)
    summary, history = result.summary, result.history
    assert summary["status"] == "completed" and summary["final_time"] == 3.0
    for name in ("to_main", "to_secondary"):
        mass = history[f"mass_{name}"] + history[f"evacuated_{name}"]
        assert np.abs(mass - mass[0]).max() <= 1e-12 * mass[0]
