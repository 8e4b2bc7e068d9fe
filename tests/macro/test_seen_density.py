"""The density people see (macro/seen_density.py): rho_s - l^2 Laplacian rho_s = rho with no flux across the
boundary. Invariants (mass, bounds, constants, zero) and the kernel's spread 4 l^2 under refinement."""

import numpy as np
import pytest

from femcrowd.macro.seen_density import SEEN_LENGTH, SeenDensity
from femcrowd.mesh.domain import load_domain

from ..support import MESHES


def test_the_seen_density_keeps_mass_bounds_constants_and_zero():
    domain = load_domain(MESHES / "square.msh")
    seen = SeenDensity(domain, length=0.3)
    rng = np.random.default_rng(1)
    rho = rng.random(domain.ncells) * (domain.centroid[:, 0] < -0.2)
    rho_s = seen(rho)
    assert abs(domain.area @ rho_s - domain.area @ rho) < 1e-12 * (domain.area @ rho)
    assert rho_s.min() >= 0 and rho_s.max() <= rho.max()
    assert rho_s.max() < 0.9 * rho.max() and (rho_s[domain.centroid[:, 0] > 0] > 0).any()   # it spreads
    assert np.abs(seen(np.full(domain.ncells, 0.7)) - 0.7).max() < 1e-13
    assert not seen(np.zeros(domain.ncells)).any()


def spread(refine, length):
    """Second moment of what a crowd in the centre cell of meshes/square.msh ([-1, 1]^2, Delaunay) sees, about
    that cell's centroid."""
    domain = load_domain(MESHES / "square.msh", refine=refine)
    centre = int(np.argmin(np.hypot(*domain.centroid.T)))
    rho = np.zeros(domain.ncells)
    rho[centre] = 1.0
    mass = domain.area * SeenDensity(domain, length)(rho)
    return mass @ np.sum((domain.centroid - domain.centroid[centre]) ** 2, axis=1) / mass.sum()


def test_the_spread_converges_to_the_kernels():
    """The kernel K_0(r / l) / (2 pi l^2) has the second moment 4 l^2 (l = 0.04, 25 l from the walls): the
    discrete one converges to it at second order (on a mesh of right triangles, whose two-point fluxes are
    clipped, it would not)."""
    length = 0.04
    errors = [abs(spread(refine, length) / (4 * length**2) - 1) for refine in (1, 2, 3)]
    rates = np.log2(np.divide(errors[:-1], errors[1:]))
    assert errors[-1] < 2e-5 and rates.min() > 1.5, (errors, rates)


def test_the_default_spread_is_the_one_of_the_discs_circle():
    """4 l^2 = R^2 / 2, the second moment of the uniform circle of R = 1 m (micro/density.py)."""
    from femcrowd.micro.density import DENSITY_RADIUS

    assert 4 * SEEN_LENGTH**2 == pytest.approx(DENSITY_RADIUS**2 / 2, rel=1e-15)
