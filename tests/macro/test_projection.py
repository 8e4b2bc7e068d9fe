"""The correction step: exact LCP solution, invariants, singular and warm-started cases."""

import numpy as np
import pytest
import scipy.optimize

from femcrowd.mesh import Boundary

from ..support import Projector
from ..support import unit_square as square_domain


def check_lcp(domain, rho_tilde, rho, phi, tol=1e-9):
    """The discrete properties of the correction step (docs/model.md)."""
    area = domain.area
    assert np.all(np.isfinite(rho)) and np.all(np.isfinite(phi))
    assert phi.min() >= 0
    assert rho.min() >= 0
    assert rho.max() <= 1 + tol
    assert np.all(phi[rho < 1 - tol] == 0)
    w = area * (1 - rho)
    assert np.allclose(w, area * (1 - rho_tilde) + Boundary(domain).at(0).laplacian() @ phi, atol=1e-12)


def test_lcp_matches_an_independent_solver():
    """PDAS result == the minimiser of the LCP's quadratic program (A SPD), by L-BFGS-B."""
    domain = square_domain(4, exits=["left"])
    rng = np.random.default_rng(0)
    rho_tilde = rng.uniform(0.2, 1.6, domain.ncells)
    rho, phi, info = Projector(domain)(rho_tilde)
    check_lcp(domain, rho_tilde, rho, phi)
    A, b = Boundary(domain).at(0).laplacian().toarray(), domain.area * (1 - rho_tilde)
    # LCP(w = A phi + b), A SPD <=> min 1/2 phi.A phi + b.phi over phi >= 0
    #                          <=> min |L^T phi + L^-1 b|^2 over phi >= 0, A = L L^T
    L = np.linalg.cholesky(A)
    ref = scipy.optimize.lsq_linear(L.T, -np.linalg.solve(L, b), bounds=(0, np.inf),
                                    method="bvls", tol=1e-14).x
    assert np.allclose(phi, ref, rtol=0, atol=1e-9 * phi.max())
    assert info["iterations"] <= 10


def test_nothing_to_do_when_nothing_exceeds_one():
    domain = square_domain(4)
    rho_tilde = np.linspace(0, 1, domain.ncells)
    rho, phi, info = Projector(domain)(rho_tilde)
    assert info["iterations"] == 0 and np.all(phi == 0) and np.array_equal(rho, rho_tilde)


def test_mass_conserved_and_exit_flux_accounted():
    domain = square_domain(8, exits=["left"])
    rho_tilde = np.where(domain.centroid[:, 0] < 0.5, 1.5, 0.2)
    rho, phi, _ = Projector(domain)(rho_tilde)
    exit = Boundary(domain).at(0).exit
    exit_T = np.bincount(domain.f2t[0][exit], domain.transmissibility[exit], domain.ncells)
    lost = exit_T @ phi
    assert lost > 0
    assert abs(domain.area @ rho + lost - domain.area @ rho_tilde) < 1e-13 * (domain.area @ rho_tilde)


def test_closed_room_fully_saturated_is_the_singular_case():
    """Mass = area in a closed room: A_SS is pure Neumann; the answer is rho = 1 and min phi = 0."""
    domain = square_domain(8)
    x = domain.centroid
    bump = np.where(x[:, 0] + x[:, 1] < 0.6, 0.3, 0.0)
    rho_tilde = 1 + bump - (domain.area @ bump) / domain.area.sum()  # mean exactly 1, some cells > 1
    rho, phi, info = Projector(domain)(rho_tilde)
    assert np.abs(rho - 1).max() < 1e-9
    assert phi.min() == 0 and phi.max() > 0
    assert abs(domain.area @ rho - domain.area @ rho_tilde) < 1e-12


def test_warm_start_gives_the_same_answer_in_fewer_iterations():
    domain = square_domain(16, exits=["left"])
    x = domain.centroid
    projection = Projector(domain)
    first = np.where(np.hypot(x[:, 0] - 0.5, x[:, 1] - 0.5) < 0.3, 1.4, 0.5)
    projection(first)
    second = first * (1 + 0.01 * np.sin(7 * x[:, 0]))
    rho_warm, phi_warm, info_warm = projection(second)
    rho_cold, phi_cold, info_cold = Projector(domain)(second)
    assert np.allclose(phi_warm, phi_cold, atol=1e-12 * phi_cold.max())
    assert info_warm["iterations"] <= info_cold["iterations"]
    assert info_warm["iterations"] <= 3


@pytest.mark.parametrize("c", [1.0 + 1e-12, 50.0])
def test_extreme_oversaturation_keeps_bounds(c):
    domain = square_domain(16, exits=["left", "right"])
    x = domain.centroid
    rho_tilde = np.where(np.hypot(x[:, 0] - 0.5, x[:, 1] - 0.5) < 0.1, c, 0.0)
    rho, phi, _ = Projector(domain)(rho_tilde)
    check_lcp(domain, rho_tilde, rho, phi)


def test_facet_fluxes_are_the_correction():
    """The pressure flux T_e (phi_K - phi_L) of every facet: summed per cell it is the correction A phi,
    through the exit facets it is the evacuated mass, through walls nothing."""
    domain = square_domain(8, exits=["left"])
    rho_tilde = np.where(domain.centroid[:, 0] < 0.5, 1.5, 0.2)
    exits = Boundary(domain).at(0.0)
    projection = Projector(domain)
    flux, _ = projection.projection(rho_tilde)
    G = flux.facet_flux(domain, exits)
    k0, k1 = domain.f2t
    inner = domain.interior
    net = np.bincount(k0, G, domain.ncells) - np.bincount(k1[inner], G[inner], domain.ncells)
    outflow = np.zeros(domain.ncells)
    outflow[flux.cells] = flux.outflow
    assert np.allclose(net, outflow, rtol=0, atol=1e-12 * np.abs(G).max())
    assert np.all(G[exits.wall] == 0) and G[exits.exit].sum() > 0
    rho = flux.apply(rho_tilde, domain.area)
    assert domain.area @ rho + G[exits.exit].sum() == pytest.approx(domain.area @ rho_tilde, rel=1e-14)


@pytest.mark.parametrize("cells", [[], [5], [7, 2, 2, 0], "all", "reversed"])
def test_gathered_rows_are_scipys(cells):
    """linalg/rows.py, the projection's A[S] without scipy's indexing: the same indptr, indices and data, in the
    same order, for any list of cells (empty, repeated, unsorted), on the Laplacian of a mesh with an exit."""
    from femcrowd.linalg.rows import rows

    domain = square_domain(8, exits=("right",))
    A = Boundary(domain).at(0).laplacian()
    n = A.shape[0]
    cells = np.arange(n) if cells == "all" else np.arange(n)[::-1] if cells == "reversed" else np.array(cells, np.intp)
    ours, theirs = rows(A, cells), A[cells]
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(ours, name), getattr(theirs, name)), name


@pytest.mark.parametrize("cells", [[5], [7, 2, 0], "all", "reversed", "random"])
def test_band_system_from_gathered_rows_is_scipys_bit_for_bit(cells):
    """The predictor's band solves (warm_start.py) take A[B] @ phi and the lower triangle of A_BB from the gathered
    rows (linalg/rows.py matvec, lower_block) instead of scipy's indexing: the same numbers bit for bit, so the
    factorisations and the runs are unchanged, for unsorted sets of distinct cells."""
    from femcrowd.linalg.cholmod import lower_pattern
    from femcrowd.linalg.rows import lower_block, matvec, rows

    domain = square_domain(8, exits=("right",))
    A = Boundary(domain).at(0).laplacian().tocsr()
    n = A.shape[0]
    rng = np.random.default_rng(4)
    cells = {"all": np.arange(n), "reversed": np.arange(n)[::-1],
             "random": rng.permutation(n)[:n // 3]}.get(cells) if isinstance(cells, str) else np.array(cells, np.intp)
    gathered = rows(A, cells)
    for ours, theirs in zip(lower_block(gathered, cells), lower_pattern(A[cells][:, cells])):
        assert np.array_equal(ours, theirs)
    x = rng.normal(size=n)
    assert np.array_equal(matvec(gathered, x), A[cells] @ x)
