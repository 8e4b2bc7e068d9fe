"""Reuse of factorisations / AMG hierarchies and warm starts give the result of a fresh solve."""

import numpy as np
import pytest

from femcrowd.case import Expression
from femcrowd.linalg import envelope
from femcrowd.linalg.envelope import BORDER_MAX, EnvelopeCholesky
from femcrowd.macro import MacroState
from femcrowd.macro.projection import warm_start
from femcrowd.macro.projection.sets import adjacency_table
from femcrowd.macro.projection.warm_start import PREDICT_MIN
from femcrowd.macro.transport import UpwindTransport
from femcrowd.macro.velocity import FieldVelocity
from femcrowd.mesh import Boundary, load_domain

from ..support import MESHES, Projector


def pushed_crowd():
    """A crowd pushed against the wall of a one-door room, S grows and moves every step: the domain,
    the initial density and the prediction step rho -> rho~."""
    domain = load_domain(MESHES / "room_one_door.msh", ["exit"])
    exits = Boundary(domain).at(0.0)
    velocity = FieldVelocity(domain, Expression("1"), Expression("0.3 * (3 - y)"))
    state = MacroState.initial(np.zeros((1, domain.ncells)), 1)
    transport = UpwindTransport(domain, exits, velocity.normal_on_facets(state, exits))
    rho0 = np.where(domain.centroid[:, 0] > 5, 0.95, 0.0)
    return domain, rho0, lambda rho: transport.step(rho, 0.9 * transport.max_dt)[0]


@pytest.mark.parametrize("direct_max, predict_min, keep_forward",
                         [(1_000_000, PREDICT_MIN, False), (1_000_000, 0, False), (1_000_000, 0, True),
                          (0, PREDICT_MIN, False)],
                         ids=["factorisation", "factorisation+predictor", "factorisation+predictor+forward", "amg"])
def test_reused_solvers_match_fresh_solves_over_a_sequence_of_steps(direct_max, predict_min, keep_forward,
                                                                     monkeypatch):
    """The kept Projection (warm-started S and phi, solver reused while S changes by a few
    cells; the predictor, forced on this small mesh, or not; the forward substitution of b kept for the bordered
    solves, forced on, or not) and a fresh Projection per step (cold start, exact sparse direct solve) see the
    same rho~ each step and agree to 1e-10.
    """
    monkeypatch.setattr(warm_start, "PREDICT_MIN", predict_min)
    if keep_forward:
        monkeypatch.setattr(envelope, "KEEP_FORWARD_MIN", 0)
    domain, rho, advance = pushed_crowd()
    kept = Projector(domain, direct_max=direct_max)
    solves, cold, rebuilds, band_solves, sizes = 0, 0, 0, 0, set()
    for _ in range(20):
        rho_tilde = advance(rho)
        rho_ref, phi_ref, info_ref = Projector(domain)(rho_tilde)
        rho_kept, phi_kept, info = kept(rho_tilde)
        assert np.abs(phi_kept - phi_ref).max() <= 1e-10 * phi_ref.max()
        assert np.abs(rho_kept - rho_ref).max() <= 1e-10
        assert rho_kept.max() <= 1 + 1e-9 and phi_kept.min() >= 0
        solves += info["iterations"]
        cold += info_ref["iterations"]
        rebuilds += info["rebuilds"]
        band_solves += info["band_solves"]
        sizes.add(info["unknowns"])
        rho = rho_ref
    assert len(sizes) > 10          # S changed (almost) every step: the reuse paths were exercised
    assert solves <= cold           # the warm start saves active-set iterations
    assert rebuilds < solves        # and the kept solver served some of them (reuse=False: equal)
    assert (band_solves > 0) == (predict_min == 0 and direct_max > 0)  # the predictor ran when asked


def test_predictor_saves_active_set_iterations_and_factorisations(monkeypatch):
    """The front of the pushed crowd moves by several cells per step. Started from the kept
    factorisation and band solves (forced on this small mesh), the exact iterations need about one
    solve per step: on 30 steps, under 0.6 times the iterations and fewer factorisations than
    with the sandpile guess alone (measured: 36 against 82 iterations, 33 against 48 factorisations)."""
    totals = {}
    for predict_min in (0, 10**9):
        monkeypatch.setattr(warm_start, "PREDICT_MIN", predict_min)
        domain, rho, advance = pushed_crowd()
        kept = Projector(domain)
        iterations = factorizations = band_solves = 0
        for step in range(30):
            rho, phi, info = kept(advance(rho))
            if step:  # warm-started steps
                iterations += info["iterations"]
                factorizations += info["factorizations"]
                band_solves += info["band_solves"]
        totals[predict_min > 0] = iterations, factorizations, band_solves
    iterations, factorizations, band_solves = totals[False]
    plain_iterations, plain_factorizations, none = totals[True]
    assert band_solves > 0 and none == 0
    assert iterations < 0.6 * plain_iterations
    assert factorizations < plain_factorizations


def test_predictor_keeps_the_cells_that_left_S_out_of_its_factorised_solve(monkeypatch):
    """A queue that drains from its rear: S = the cells right of a rear line that moves 0.4 m per step (about 150
    cells leave S each step). The predictor's solve with the last factor counts the cells that left S as cells
    without an equation (before: with their spare capacity 1 - rho~, which pulled phi down over the rear of the
    queue and left the exact iterations a second factorisation): most steps now take one factorisation
    (measured: 8 of 11 warm steps, 15 factorisations; before 2 of 11, 22), and every step equals a fresh solve."""
    monkeypatch.setattr(warm_start, "PREDICT_MIN", 0)
    domain = load_domain(MESHES / "room_one_door.msh", ["exit"])
    x, y = domain.centroid.T
    kept = Projector(domain)
    single = 0
    for step in range(12):
        rho_tilde = np.where(x > 2.0 + 0.4 * step, 1.0 + 0.003 * (10 - x) + 0.01 * np.sin(3 * y), 0.6)
        rho, phi, info = kept(rho_tilde)
        rho_ref, phi_ref, _ = Projector(domain)(rho_tilde)
        assert np.abs(phi - phi_ref).max() <= 1e-10 * phi_ref.max()
        assert np.abs(rho - rho_ref).max() <= 1e-10 and rho.max() <= 1 + 1e-9 and phi.min() >= 0
        single += step > 0 and info["factorizations"] == 1
    assert single >= 8


def test_advance_carries_a_growing_front_further_and_keeps_the_exact_solution(monkeypatch):
    """A queue whose front moves 0.5 m (about 4 cells) per step into a crowd at 0.9: after an exact iteration that
    grows S, the band solves from its phi and factor (advance, forced on this small mesh) carry the front where
    the sandpile spill moves it a few cells: fewer factorisations over 10 steps (measured: 21 against 30), and
    every step equals the plain active-set solve (the spill, a fresh Projection) to 1e-10."""
    monkeypatch.setattr(warm_start, "PREDICT_MIN", 0)
    domain = load_domain(MESHES / "room_one_door.msh", ["exit"])
    x, y = domain.centroid.T
    factorisations, band_solves = {}, {}
    for advance in (False, True):
        monkeypatch.setattr(warm_start, "ADVANCE_MIN", 0 if advance else 10**9)
        kept = Projector(domain)
        factorisations[advance] = band_solves[advance] = 0
        for step in range(10):
            rho_tilde = np.where(x > 7.0 - 0.5 * step, 1.03, 0.9) + 0.005 * np.sin(2 * y)
            rho, phi, info = kept(rho_tilde)
            factorisations[advance] += info["factorizations"]
            band_solves[advance] += info["band_solves"]
            monkeypatch.setattr(warm_start, "ADVANCE_MIN", 10**9)
            rho_ref, phi_ref, _ = Projector(domain)(rho_tilde)
            monkeypatch.setattr(warm_start, "ADVANCE_MIN", 0 if advance else 10**9)
            assert np.abs(phi - phi_ref).max() <= 1e-10 * phi_ref.max()
            assert np.abs(rho - rho_ref).max() <= 1e-10 and rho.max() <= 1 + 1e-9 and phi.min() >= 0
    assert band_solves[True] > band_solves[False]   # advance ran
    assert factorisations[True] <= 0.8 * factorisations[False]


def test_adjacency_table_lists_the_off_diagonal_entries_of_A():
    domain = load_domain(MESHES / "room_one_door.msh", ["exit"])
    A = Projector(domain).projection.A
    table = adjacency_table(A)
    for cell in (0, 17, domain.ncells - 1):
        row = A[cell]
        expected = set(row.indices[(row.indices != cell) & (row.data != 0)])
        assert set(table[cell]) - {cell} == expected


def test_envelope_factorisation_solves_every_saturated_set_inside_it():
    """One symbolic analysis on an envelope E, numeric refactorisations for several S inside it:
    each solve equals a sparse LU solve of A_SS (pattern of K kept, values masked)."""
    import scipy.sparse.linalg as spla

    domain = load_domain(MESHES / "room_one_door.msh", ["exit"])
    A = Boundary(domain).at(0.0).laplacian().tocsr()
    x = domain.centroid[:, 0]
    envelope = np.flatnonzero(x > 4.0)
    factor = EnvelopeCholesky(A, envelope, len(envelope))
    rng = np.random.default_rng(3)
    for threshold in (7.0, 5.0, 6.0, 4.5):  # S grows, shrinks and grows again inside E
        S = np.flatnonzero(x > threshold)
        assert factor.fits(S) == (len(S) >= 0.6 * len(envelope))  # made for S = E here
        assert factor.prepare(S)  # a new S: one numeric factorisation
        rhs = rng.uniform(0.5, 1.0, len(S)) * domain.area[S]
        reference = spla.spsolve(A[S][:, S].tocsc(), rhs)
        assert np.abs(factor.solve(S, rhs) - reference).max() <= 1e-10 * np.abs(reference).max()
        assert not factor.prepare(S)  # the same S again: none
    assert not factor.fits(np.flatnonzero(x > 3.0))  # S leaves E: a new envelope is needed


def _factorised_room():
    """The room's Laplacian A, S_0 (the cells right of x = 6 m) and an envelope Cholesky factor of A_{S_0 S_0}."""
    domain = load_domain(MESHES / "room_one_door.msh", ["exit"])
    A = Boundary(domain).at(0.0).laplacian().tocsr()
    x = domain.centroid[:, 0]
    S0 = np.flatnonzero(x > 6.0)
    factor = EnvelopeCholesky(A, np.flatnonzero(x > 4.0), len(S0))
    assert factor.prepare(S0)
    return domain, A, S0, factor


@pytest.mark.parametrize("grown", [1, 2, BORDER_MAX])
def test_bordered_solve_of_a_few_new_cells_equals_a_fresh_solve(grown):
    """S_0 factorised, S = S_0 + a few cells (neighbours of S_0, and cells that touch only each other):
    the bordered solve (Schur complement on the new cells) needs no factorisation and equals sparse LU."""
    import scipy.sparse.linalg as spla

    domain, A, S0, factor = _factorised_room()
    front = np.setdiff1d(A[S0].indices, S0)                 # the neighbour layer of S_0
    second = np.setdiff1d(A[front].indices, np.union1d(S0, front))
    J = np.concatenate([front[:grown - grown // 2], second[:grown // 2]])  # coupled to S_0 and/or each other
    S = np.union1d(S0, J)
    assert len(S) == len(S0) + grown
    assert not factor.prepare(S)
    rhs = np.random.default_rng(grown).uniform(0.5, 1.0, len(S)) * domain.area[S]
    reference = spla.spsolve(A[S][:, S].tocsc(), rhs)
    assert np.abs(factor.solve(S, rhs) - reference).max() <= 1e-10 * np.abs(reference).max()
    assert factor.prepare(np.union1d(S, front[:BORDER_MAX + 1]))  # too many new cells: factorise


@pytest.mark.parametrize("joined, left", [(0, 1), (2, 3), (0, BORDER_MAX), (BORDER_MAX // 2, BORDER_MAX // 2)])
def test_bordered_solve_of_cells_that_joined_and_left_equals_a_fresh_solve(joined, left):
    """S_0 factorised, S = S_0 without a few of its cells (D: inside S_0 and on its front) and with a few new ones:
    the bordered solve (x_D = 0 by multipliers) needs no factorisation and equals sparse LU on A_SS."""
    import scipy.sparse.linalg as spla

    domain, A, S0, factor = _factorised_room()
    front = np.setdiff1d(A[S0].indices, S0)
    edge = np.intersect1d(A[front].indices, S0)                # the cells of S_0 next to its front
    D = np.concatenate([edge[:left - left // 2], S0[len(S0) // 2:][:left // 2]])
    S = np.union1d(np.setdiff1d(S0, D), front[:joined])
    assert len(S) == len(S0) + joined - left
    assert not factor.prepare(S)
    rhs = np.random.default_rng(joined + 7 * left).uniform(0.5, 1.0, len(S)) * domain.area[S]
    reference = spla.spsolve(A[S][:, S].tocsc(), rhs)
    assert np.abs(factor.solve(S, rhs) - reference).max() <= 1e-10 * np.abs(reference).max()
    assert factor.prepare(np.setdiff1d(S0, edge[:BORDER_MAX + 1]))  # too many cells left: factorise


@pytest.mark.parametrize("joined, left", [(1, 0), (BORDER_MAX, 0), (2, 3)])
def test_bordered_solve_after_a_solve_on_S0_reuses_its_forward_substitution(joined, left, monkeypatch):
    """The next active-set iteration of a step solves with the same b: the bordered solve takes the kept
    L^{-1} P b_0 of the solve on S_0 (b_0 on the cells D that left only changes their multipliers) and substitutes
    only the columns of the cells joined and left (counted here), and equals sparse LU on A_SS; a different b on
    S_0 substitutes b_0 again, as without the reuse."""
    import scipy.sparse.linalg as spla

    monkeypatch.setattr(envelope, "KEEP_FORWARD_MIN", 0)   # the room is smaller than a run where it pays
    domain, A, S0, factor = _factorised_room()
    columns = []
    forward = factor._forward
    monkeypatch.setattr(factor, "_forward", lambda b: columns.append(b.shape[1:] or (1,)) or forward(b))
    front = np.setdiff1d(A[S0].indices, S0)
    edge = np.intersect1d(A[front].indices, S0)
    S = np.union1d(np.setdiff1d(S0, edge[:left]), front[:joined])
    rng = np.random.default_rng(joined)
    b = rng.uniform(0.5, 1.0, domain.ncells) * domain.area
    for same in (True, False):
        b0 = b[S0] if same else 1.1 * b[S0]
        reference = spla.spsolve(A[S0][:, S0].tocsc(), b0)
        assert np.abs(factor.solve(S0, b0) - reference).max() <= 1e-10 * np.abs(reference).max()
        columns.clear()
        reference = spla.spsolve(A[S][:, S].tocsc(), b[S])
        assert np.abs(factor.solve(S, b[S]) - reference).max() <= 1e-10 * np.abs(reference).max()
        assert columns == [(joined + left + (not same),)]
