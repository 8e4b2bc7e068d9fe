"""Microscopic (disc) model: catching-up scheme, exact projection, sampling, exits."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.micro import MicroSimulation, project
from femcrowd.micro.contacts import CandidateList, WallSet, merge_collinear
from femcrowd.micro.projection import NewtonPattern, kkt_residual
from femcrowd.micro.sampling import read_discs_csv, sample_discs, target_count

from ..support import CASES


def box(x0, y0, x1, y1):
    return np.array([[[x0, y0], [x1, y0]], [[x1, y0], [x1, y1]], [[x1, y1], [x0, y1]], [[x0, y1], [x0, y0]]], float)


def room_with_door(L, y0, y1):
    """Square room [0, L]^2 with a door x = L, y in [y0, y1]."""
    walls = np.array([[[0, 0], [L, 0]], [[L, 0], [L, y0]], [[L, y1], [L, L]], [[L, L], [0, L]], [[0, L], [0, 0]]],
                     float)
    exits = np.array([[[L, y0], [L, y1]]], float)
    return walls, exits


def crowd_in_room_with_door(L, r, density, seed):
    """Discs of radius r sampled at a density in the room of :func:`room_with_door` (door 1 m wide, in the
    middle of the wall x = L): centres, radii, walls, exits."""
    walls, exits = room_with_door(L, L / 2 - 0.5, L / 2 + 0.5)
    P = np.array([[0, 0], [L, 0], [L, L], [0, L]], float)
    T = np.array([[0, 1, 2], [0, 2, 3]])
    q, rr = sample_discs(density, P, T, r, walls=np.concatenate([walls, exits]), seed=seed)
    return q, rr, walls, exits


def pairwise_min_gap(q, r):
    if len(q) < 2:
        return np.inf
    d = np.linalg.norm(q[:, None] - q[None], axis=-1) - r[:, None] - r[None]
    d[np.diag_indices(len(q))] = np.inf
    return d.min()


def test_head_on_discs_move_together_at_mean_speed():
    q = np.array([[0.0, 0.0], [1.5, 0.0]])
    U = lambda x, t: np.array([[2.0, 0.0], [-1.0, 0.0]])  # noqa: E731
    sim = MicroSimulation(q, 0.5, None, None, U, tau=0.01)
    in_contact = 0
    gap = 0.5
    for info in sim.run(max_steps=60):
        assert info.max_overlap < 1e-12
        if gap < 1e-12:  # in contact at the start of the step
            in_contact += 1
            assert np.abs(info.u - [0.5, 0.0]).max() < 1e-10
            assert np.isclose(info.pressure[0], 1.5) and np.isclose(info.pressure[1], 1.5)
        gap = np.linalg.norm(sim.q[1] - sim.q[0]) - 1.0
    assert in_contact > 30
    # before contact nobody is slowed down
    sim = MicroSimulation(q, 0.5, None, None, U, tau=0.01)
    assert np.abs(sim.step().u - [[2, 0], [-1, 0]]).max() < 1e-14


def test_chain_pushed_against_wall_stops_without_overlap():
    n, r = 12, 0.2
    rng = np.random.default_rng(3)
    x = 0.5 + np.cumsum(2 * r + rng.uniform(0.01, 0.1, n))
    q = np.c_[x, np.full(n, 1.0)]
    walls = np.array([[[0.0, -1.0], [0.0, 3.0]]])
    sim = MicroSimulation(q, r, walls, None, lambda x, t: np.tile([-1.0, 0.0], (len(x), 1)), tau=0.02)
    for info in sim.run(max_steps=400):
        assert info.max_overlap < 1e-9 * r
        assert info.converged and info.kkt < 1e-10
    assert np.abs(info.u).max() < 1e-10
    assert np.allclose(np.sort(sim.q[:, 0]), r + 2 * r * np.arange(n), atol=1e-9)
    # the wall carries the whole chain: pressure grows towards the wall (lambda_k = k)
    order = np.argsort(sim.q[:, 0])
    assert np.all(np.diff(info.pressure[order]) < 0)


def test_disc_slides_along_wall_with_tangential_velocity():
    r = 0.5
    walls = np.array([[[-50.0, 0.0], [50.0, 0.0]]])
    sim = MicroSimulation([[0.0, 0.8]], r, walls, None, lambda x, t: np.array([[1.0, -1.0]]), tau=0.01)
    touched = 0
    for info in sim.run(max_steps=200):
        assert sim.q[0, 1] - r > -1e-12
        if abs(sim.q[0, 1] - r) < 1e-12 and info.contacts:
            touched += 1
            assert np.abs(info.u[0] - [1.0, 0.0]).max() < 1e-11
            assert np.isclose(info.pressure[0], 1.0)
    assert touched > 100


def test_wall_segments_are_merged():
    pieces = np.array([[[0, 0], [1, 0]], [[1, 0], [2.5, 0]], [[2.5, 0], [4, 0]], [[4, 0], [4, 1]]], float)
    merged = merge_collinear(pieces[np.random.default_rng(0).permutation(4)])
    assert len(merged) == 2
    lengths = sorted(np.linalg.norm(merged[:, 1] - merged[:, 0], axis=1))
    assert np.allclose(lengths, [1.0, 4.0])


def _jammed_boxes(nbox=100, seed=0, steps=40):
    """nbox independent 2 x 2 boxes, each with ~12 discs pushed into a corner."""
    rng = np.random.default_rng(seed)
    walls, q, r, corner = [], [], [], []
    side = int(np.ceil(np.sqrt(nbox)))
    for b in range(nbox):
        x0, y0 = 3.0 * (b % side), 3.0 * (b // side)
        walls.append(box(x0, y0, x0 + 2, y0 + 2))
        pts, rad = [], []
        while len(pts) < 12:
            p = rng.uniform([x0 + 0.25, y0 + 0.25], [x0 + 1.75, y0 + 1.75])
            rr = rng.uniform(0.15, 0.25)
            if all(np.hypot(*(p - o)) > rr + ro for o, ro in zip(pts, rad)):
                pts.append(p)
                rad.append(rr)
        q += pts
        r += rad
        c = np.array([x0, y0]) + rng.choice([0.0, 2.0], 2)
        corner += [c] * len(pts)
    corner = np.array(corner)

    def U(x, t):
        v = corner[: len(x)] - x
        return v / np.linalg.norm(v, axis=1)[:, None]

    sim = MicroSimulation(np.array(q), np.array(r), np.concatenate(walls), None, U, tau=0.05)
    for _ in sim.run(max_steps=steps):
        pass
    return sim, np.arange(len(q)) // 12


def test_exact_and_uzawa_agree_on_jammed_configurations():
    sim, group = _jammed_boxes()
    cl = CandidateList(sim.q, sim.r, sim.contacts.walls, skin=0.05)
    C = cl.constraints(sim.q, sim.r, sim.contacts.walls)
    assert (C.D < 1e-9).sum() > 15 * 100 / 2  # jammed: many touching pairs
    rng = np.random.default_rng(1)
    U = rng.normal(size=(C.N, 2))
    d = np.maximum(C.D, 0) / 0.05
    ex = project(C, U, d)
    uz = project(C, U, d, method="uzawa", tol=1e-12, max_iter=400_000)
    assert ex.converged and ex.kkt < 1e-10
    assert uz.converged, uz.kkt
    err = np.abs(ex.u - uz.u).max(axis=1)
    per_box = np.bincount(group, weights=err) / 12
    assert len(per_box) == 100 and err.max() < 1e-8
    assert ex.active > 0 and kkt_residual(C, U, d, ex.u, ex.lam) < 1e-10


def test_projection_handles_hyperstatic_cluster():
    # Maury 2014, Fig. 3: more contacts than degrees of freedom (B B^T singular)
    s = 2.0
    X, Y = np.meshgrid(np.arange(5), np.arange(4))
    q = np.c_[X.ravel() + 0.5 * (Y.ravel() % 2), Y.ravel() * np.sqrt(3) / 2] * s
    r = np.full(len(q), s / 2)
    cl = CandidateList(q, r, None, skin=1e-6)
    C = cl.constraints(q, r, None)
    assert C.m > 2 * len(q) - 3  # hyperstatic
    U = -(q - q.mean(0)) + np.random.default_rng(0).normal(scale=0.1, size=q.shape)  # compress
    d = np.maximum(C.D, 0) / 0.1
    res = project(C, U, d)
    assert res.converged and res.kkt < 1e-11
    assert C.matvec(res.u).max() <= 1e-11 and res.active > 10
    uz = project(C, U, d, method="uzawa", tol=1e-13, max_iter=200_000)
    assert np.abs(res.u - uz.u).max() < 1e-9


def test_sampling_no_overlap_inside_reproducible():
    P = np.array([[0, 0], [4, 0], [4, 3], [0, 3]], float)
    T = np.array([[0, 1, 2], [0, 2, 3]])
    walls = box(0, 0, 4, 3)
    dens = lambda x: 0.2 + 0.3 * x[:, 0] / 4  # noqa: E731
    n = target_count(dens, P, T, 0.1)
    expect = (0.2 + 0.15) * 12 * (np.pi / (2 * np.sqrt(3))) / (np.pi * 0.01)
    assert abs(n - expect) <= 1
    q, r = sample_discs(dens, P, T, 0.1, walls=walls, seed=7)
    assert len(q) == n
    assert pairwise_min_gap(q, r) >= 0
    assert np.all(WallSet(walls).distance(q) >= r - 1e-12)
    assert np.all((q > 0) & (q < [4, 3]))
    q2, _ = sample_discs(dens, P, T, 0.1, walls=walls, seed=7)
    q3, _ = sample_discs(dens, P, T, 0.1, walls=walls, seed=8)
    assert np.array_equal(q, q2) and not np.array_equal(q, q3)
    # more people where the density is higher
    assert (q[:, 0] > 2).sum() > (q[:, 0] < 2).sum()
    # polydisperse, explicit count
    qp, rp = sample_discs(0.5, P, T, [0.08, 0.12], count=150, seed=1)  # walls: mesh boundary
    assert len(qp) == 150 and rp.min() >= 0.08 and rp.max() <= 0.12 and np.ptp(rp) > 0.02
    assert pairwise_min_gap(qp, rp) >= 0 and np.all(WallSet(walls).distance(qp) >= rp - 1e-12)


def test_read_discs_csv(tmp_path):
    f = tmp_path / "discs.csv"
    f.write_text("x,y,r\n1.0,2.0,0.2\n3.0,4.0,0.25\n")
    q, r = read_discs_csv(f)
    assert q.tolist() == [[1.0, 2.0], [3.0, 4.0]] and r.tolist() == [0.2, 0.25]
    f.write_text("x,y,r\n1.0,2.0,0.2\n\n# a comment\n3.0,4.0,0.25\n")
    assert read_discs_csv(f, lines=True)[2].tolist() == [2, 5]   # the lines of the file, for the errors
    (tmp_path / "bad.csv").write_text("x,y\n1,2\n")
    with pytest.raises(ValueError, match="bad.csv"):
        read_discs_csv(tmp_path / "bad.csv")


def test_small_room_evacuates_without_overlap():
    L, r = 4.0, 0.15
    q, rr, walls, exits = crowd_in_room_with_door(L, r, 0.35, seed=2)
    door = np.array([L, 2.0])

    def U(x, t):
        v = np.where(np.abs(x[:, 1:2] - 2.0) < 0.5 - r, [1.0, 0.0], door - x)
        return v / np.linalg.norm(v, axis=1)[:, None]

    sim = MicroSimulation(q, rr, walls, exits, U, tau=0.02)
    N0 = len(q)
    assert N0 > 40
    wallset = WallSet(walls)
    ids_seen = set()
    for info in sim.run(max_steps=3000):
        assert info.max_overlap < 1e-9 * r and info.overlap_r < 1e-9
        assert info.converged or (0 < info.gap <= 1e-7)   # exact, or the certified accuracy of a jam
        if info.count:
            assert pairwise_min_gap(sim.q, sim.r) > -1e-9 * r
            assert np.all(wallset.distance(sim.q) - sim.r > -1e-9 * r)
            assert np.all((sim.q > 0) & (sim.q < L))  # every centre inside the room
        ids_seen.update(info.ids.tolist())
        assert info.count + info.evacuated == N0
    assert sim.count == 0 and sim.evacuated == N0


def test_a_warm_jam_is_projected_to_its_certified_accuracy():
    """Warm-started with a jam's multipliers (as many active contacts as discs), the projection goes to the
    interior point: its velocities are strictly feasible and their objective is within the relative gap it
    certifies of the exact minimum; with gap_tol = 1e-12 they agree with the exact projection."""
    sim, _ = _jammed_boxes()
    C = CandidateList(sim.q, sim.r, sim.contacts.walls, skin=0.05).constraints(sim.q, sim.r, sim.contacts.walls)
    rng = np.random.default_rng(1)
    U = rng.normal(size=(C.N, 2))
    d = np.maximum(C.D, 0) / 0.05
    jam = project(C, U, d)
    assert jam.active >= C.N
    U2 = U + rng.normal(scale=0.3, size=U.shape)
    exact = project(C, U2, d)                        # cold: KKT at round-off
    warm = project(C, U2, d, lam0=jam.lam)
    assert exact.converged and warm.fallback
    cost = lambda u: 0.5 * np.sum((u - U2) ** 2)    # noqa: E731
    assert (C.matvec(warm.u) - d).max() <= 1e-12 * np.abs(U2).max()
    assert warm.gap <= 1e-7 and cost(warm.u) - cost(exact.u) <= warm.gap * cost(warm.u) + 1e-12 * cost(exact.u)
    tight = project(C, U2, d, lam0=jam.lam, gap_tol=1e-12)
    assert np.abs(tight.u - exact.u).max() < 1e-8


def test_the_history_reports_overlap_gap_and_change():
    """cases/narrow-door-micro jams at the door: every step's overlap is below 1e-9 r and its certified gap
    below 1e-7; the jammed steps are solved by the interior point (gap or change > 0 on some)."""
    result = Simulation(load_case(CASES / "narrow-door-micro", {"time.end": 15.0})).run()
    h, s = result.history, result.summary
    assert h["overlap_r"].max() <= 1e-9 and h["gap"].max() <= 1e-7
    assert (h["change"] > 0).any() and np.all(h["change"] < 0.05)
    assert s["max_overlap_r"] == h["overlap_r"].max() and s["max_gap"] == h["gap"].max()


def test_a_kept_factorisation_pattern_gives_the_projection_of_a_fresh_one():
    """The symbolic analysis kept from a projection serves the next one with the same rows, and still serves
    after some discs left (their slots stay as identity blocks): no new analysis, the same projection."""
    sim, group = _jammed_boxes()
    constraints = lambda q, r: CandidateList(q, r, sim.contacts.walls, skin=0.05).constraints(q, r, sim.contacts.walls)  # noqa: E731
    C = constraints(sim.q, sim.r)
    U = np.random.default_rng(1).normal(size=(C.N, 2))
    d = np.maximum(C.D, 0) / 0.05
    pattern = NewtonPattern()
    first = project(C, U, d, pattern=pattern)
    analyses = pattern.analyses
    again = project(C, U, d, pattern=pattern)
    assert pattern.analyses == analyses and np.array_equal(again.u, first.u)
    kept = group != 3                                   # the discs of one box leave
    pattern.keep(kept)
    C2 = constraints(sim.q[kept], sim.r[kept])
    d2 = np.maximum(C2.D, 0) / 0.05
    after = project(C2, U[kept], d2, pattern=pattern)
    fresh = project(C2, U[kept], d2)
    assert pattern.analyses == analyses
    assert after.converged and fresh.converged and np.abs(after.u - fresh.u).max() < 1e-10


def test_a_step_that_outran_its_candidate_list_keeps_velocities_that_fit_the_rebuilt_one(monkeypatch):
    """A crowd pushed through a door: some steps move discs faster than their desired speed and outrun the
    candidate list; the list is rebuilt, and the velocities, which satisfy its new rows, are kept (one
    projection per step) with every invariant intact."""
    import femcrowd.micro.scheme as scheme

    calls = []
    real = scheme.project
    monkeypatch.setattr(scheme, "project", lambda *a, **k: calls.append(1) or real(*a, **k))
    L = 8.0
    q, rr, walls, exits = crowd_in_room_with_door(L, 0.2, 0.5, seed=3)
    door = np.array([L, 4.0])

    def U(x, t):
        v = door - x
        return v / np.linalg.norm(v, axis=1)[:, None]

    sim = MicroSimulation(q, rr, walls, exits, U, tau=0.05)
    steps = rebuilds = 0
    for info in sim.run(max_steps=150):
        steps, rebuilds = steps + 1, rebuilds + info.rebuilds
        assert info.overlap_r < 1e-9 and (info.converged or info.gap <= 1e-7)
    assert rebuilds > 1 and len(calls) == steps
