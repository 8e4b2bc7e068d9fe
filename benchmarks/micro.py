"""Benchmark of the microscopic (disc) model: room evacuation through one door.

    python benchmarks/micro.py                     # N = 2000 (20 x 20 room, 2 m door), 300 steps
    python benchmarks/micro.py --steps 0           # ... until everybody is out
    python benchmarks/micro.py --n 20000 --steps 40   # large crowd (63 x 63 room, 4 doors)
    python benchmarks/micro.py --method uzawa --steps 200
    python benchmarks/micro.py --compare-solvers --n 500   # QP solvers on one jammed projection
    python benchmarks/micro.py --steps 100 --breakdown     # where the time of a jammed step goes

Prints median / mean ms per step and the evacuation time. Reference: cromosim
(Uzawa, same room) needs 58 ms/step for N = 2000.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from femcrowd.micro import MicroSimulation  # noqa: E402
from femcrowd.micro.contacts import point_segment_distance  # noqa: E402
from femcrowd.micro.linalg import default_backend  # noqa: E402


def room(L: float, doors: list[tuple[str, float, float]]):
    """Square room [0, L]^2; doors as (side, start, end) on 'right'/'left'/'top'/'bottom'."""
    corners = {"bottom": ((0, 0), (L, 0)), "right": ((L, 0), (L, L)),
               "top": ((L, L), (0, L)), "left": ((0, L), (0, 0))}
    walls, exits = [], []
    for side, (a, b) in corners.items():
        a, b = np.array(a, float), np.array(b, float)
        cuts = sorted((s, e) for sd, s, e in doors if sd == side)
        t0 = 0.0
        for s, e in cuts:
            ts, te = s / L, e / L
            if side in ("top", "left"):  # these sides run backwards
                ts, te = 1 - te, 1 - ts
            walls.append([a + t0 * (b - a), a + ts * (b - a)])
            exits.append([a + ts * (b - a), a + te * (b - a)])
            t0 = te
        walls.append([a + t0 * (b - a), b])
    return np.array(walls), np.array(exits)


def towards_exits(exits, r):
    """U = unit vector towards the closest point of the nearest door (shrunk by r)."""
    a = exits[:, 0].copy()
    b = exits[:, 1].copy()
    t = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    a, b = a + r * t, b - r * t

    def U(x, time):
        best = np.full(len(x), np.inf)
        vec = np.zeros_like(x)
        for k in range(len(a)):
            p, dist = point_segment_distance(x, np.broadcast_to(a[k], x.shape),
                                             np.broadcast_to(b[k], x.shape))
            better = dist < best
            best[better] = dist[better]
            vec[better] = (p - x)[better]
        n = np.linalg.norm(vec, axis=1)
        out = np.zeros_like(x)
        ok = n > 0
        out[ok] = vec[ok] / n[ok, None]
        # on the door line: go straight through (outward normal of the door)
        return out

    return U


def hex_crowd(L, n, r, seed=0, spacing=None):
    """n discs of radius r on a jittered hexagonal lattice filling [0, L]^2."""
    rng = np.random.default_rng(seed)
    s = spacing or np.sqrt(L * L / (n * np.sqrt(3) / 2)) * 0.95
    s = max(s, 2 * r * 1.02)
    jit = (s - 2 * r) * 0.45 / np.sqrt(2)  # per coordinate: neighbours never overlap
    m = r + jit + 1e-3  # margin to the walls
    xs = np.arange(m, L - m, s)
    ys = np.arange(m, L - m, s * np.sqrt(3) / 2)
    X, Y = np.meshgrid(xs, ys)
    X = X + 0.5 * s * (np.arange(len(ys))[:, None] % 2)
    P = np.c_[X.ravel(), Y.ravel()]
    P = P[(P[:, 0] <= L - m)]
    if len(P) < n:
        raise ValueError(f"lattice has {len(P)} sites < {n}")
    P = P[rng.choice(len(P), n, replace=False)]
    P += rng.uniform(-jit, jit, P.shape)
    return P


def scenario(n):
    if n <= 5000:
        L = 20.0 * np.sqrt(n / 2000)
        walls, exits = room(L, [("right", L / 2 - 1, L / 2 + 1)])
    else:
        L = 20.0 * np.sqrt(n / 2000)
        c = L / 2
        walls, exits = room(L, [(s, c - 1, c + 1) for s in ("right", "left", "top", "bottom")])
    return L, walls, exits


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=2000)
    ap.add_argument("--radius", type=float, default=0.2)
    ap.add_argument("--tau", type=float, default=0.05)
    ap.add_argument("--steps", type=int, default=300, help="stop after this many steps (0: until empty)")
    ap.add_argument("--method", default="exact", choices=["exact", "uzawa"])
    ap.add_argument("--backend", default=None, help="cholmod | splu")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--compare-solvers", action="store_true")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--breakdown", action="store_true",
                    help="active-set churn per step, and the cost of the step's parts at the last state")
    ap.add_argument("--every", type=int, default=100, help="progress line every this many steps")
    args = ap.parse_args(argv)
    if args.compare_solvers:
        return compare_solvers(args)

    L, walls, exits = scenario(args.n)
    q = hex_crowd(L, args.n, args.radius, seed=args.seed)
    U = towards_exits(exits, args.radius)
    sim = MicroSimulation(q, args.radius, walls, exits, U, args.tau, method=args.method,
                          backend=args.backend, max_iter=None)
    print(f"N={args.n} room {L:.1f} m, {len(exits)} door(s) of 2 m, r={args.radius}, tau={args.tau}, "
          f"method={args.method}, backend={args.backend or default_backend()}")
    times, info = [], None
    worst_overlap = worst_kkt = 0.0
    not_conv = 0
    t0 = time.perf_counter()
    prof = None
    if args.profile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    facts, fallbacks, churn, prev_active = [], 0, [], None
    for info in sim.run(max_steps=args.steps or None):
        times.append(info.step_seconds)
        facts.append(info.factorizations)
        fallbacks += info.fallback
        if args.breakdown:
            active = active_keys(sim)
            if prev_active is not None and len(prev_active):
                churn.append(len(np.setxor1d(active, prev_active)) / len(prev_active))
            prev_active = active
        worst_overlap = max(worst_overlap, info.max_overlap)
        worst_kkt = max(worst_kkt, info.kkt)
        not_conv += not info.converged
        if info.step % args.every == 0:
            print(f"  t={info.time:7.2f} s  left={info.count:6d}  contacts={info.contacts:6d}  "
                  f"it={info.solver_iterations:3d} fact={info.factorizations:3d} kkt={info.kkt:.0e} "
                  f"step={1e3 * info.step_seconds:6.2f} ms", flush=True)
    wall = time.perf_counter() - t0
    if prof is not None:
        import pstats

        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(25)
    times = np.array(times) * 1e3
    print(f"steps={len(times)}  simulated {sim.t:.2f} s, left {sim.count}, evacuated {sim.evacuated}")
    print(f"median {np.median(times):.2f} ms/step   mean {times.mean():.2f}   p90 "
          f"{np.percentile(times, 90):.2f}   max {times.max():.1f}   wall {wall:.1f} s")
    print(f"max overlap ever {worst_overlap:.2e} m ({worst_overlap / args.radius:.1e} r), "
          f"max KKT residual {worst_kkt:.1e}, steps not converged to tol: {not_conv}")
    print(f"factorisations per step: median {np.median(facts):.0f}, max {max(facts)}; "
          f"steps that needed the interior point: {fallbacks}")
    if args.breakdown:
        breakdown(sim, churn)


def active_keys(sim):
    """Active contacts (lambda > 0) of the last step, keyed by the discs' original ids."""
    cl, big = sim.cl, 1 << 31
    keys = np.concatenate([sim.ids[cl.pi] * big + sim.ids[cl.pj], -1 - (sim.ids[cl.wi] * big + cl.ws)])
    return np.sort(keys[sim.lam > 0])


def breakdown(sim, churn):
    """Median cost of the parts of one step at the final state (20 repeats each)."""
    from femcrowd.micro.contacts import CandidateList
    from femcrowd.micro.projection import _NewtonMatrix, project

    def med(f, k=20):
        ts = []
        for _ in range(k):
            t = time.perf_counter()
            f()
            ts.append(time.perf_counter() - t)
        return 1e3 * float(np.median(ts))

    C = sim.constraints()
    U = sim.desired_velocity()
    d = np.maximum(C.D, -sim._recover) / sim.tau
    act = sim.lam > 0
    newton = _NewtonMatrix(C, act, None)
    x = np.ones((C.N, 2))
    if churn:
        print(f"active set churn per step (|A_n xor A_n-1| / |A_n-1|): median {100 * np.median(churn):.0f} %, "
              f"p90 {100 * np.percentile(churn, 90):.0f} %")
    print(f"at the last state: {C.N} discs, {C.m} candidate rows, {act.sum()} active")
    print(f"  candidate list (KD-tree) rebuild  {med(lambda: CandidateList(sim.q, sim.r, sim.walls, sim._base_skin)):7.2f} ms")
    print(f"  constraint rows (gaps, normals)   {med(lambda: sim.cl.constraints(sim.q, sim.r, sim.walls)):7.2f} ms")
    print(f"  Newton matrix symbolic analysis   {med(lambda: _NewtonMatrix(C, act, None), 5):7.2f} ms")
    print(f"  one numeric factorisation         {med(lambda: newton.factor(1e4 * act)):7.2f} ms "
          f"(I + rho B_A^T B_A, {2 * len(newton.discs)} unknowns)")
    print(f"  one solve with it                 {med(lambda: newton.fact.solve(x[newton.discs].ravel())):7.2f} ms")
    res = project(C, U, d, lam0=sim.lam)
    print(f"  the projection of the next step   {med(lambda: project(C, U, d, lam0=sim.lam), 3):7.2f} ms "
          f"({res.factorizations} factorisations, KKT {res.kkt:.1e})")


def compare_solvers(args):
    """Time exact QP solvers on the projection of a jammed crowd (cold start)."""
    import scipy.sparse as sp

    from femcrowd.micro.projection import kkt_residual, project

    L, walls, exits = scenario(args.n)
    q = hex_crowd(L, args.n, args.radius, seed=args.seed)
    U = towards_exits(exits, args.radius)
    sim = MicroSimulation(q, args.radius, walls, exits, U, args.tau)
    for info in sim.run(max_steps=int(round(3.0 / args.tau))):  # 3 s: the crowd has jammed
        pass
    C = sim.constraints()
    Ud = sim.desired_velocity()
    d = np.maximum(C.D, 0) / args.tau
    print(f"jammed projection: N={C.N} discs, m={C.m} candidate constraints")
    rows = []
    for name, kw in [("femcrowd exact (cold)", {}), ("femcrowd exact (warm)", {"lam0": sim.lam}),
                     ("femcrowd exact splu", {"backend": "splu"})]:
        t = time.perf_counter()
        res = project(C, Ud, d, **kw)
        rows.append((name, time.perf_counter() - t, res.kkt, res.u))
    t = time.perf_counter()
    res = project(C, Ud, d, method="uzawa", max_iter=5000, tol=1e-8)
    rows.append((f"uzawa ({res.iterations} it)", time.perf_counter() - t, res.kkt, res.u))
    ref = rows[0][3]
    try:
        import qpsolvers
    except ImportError:
        qpsolvers = None
        print("(qpsolvers not installed: pip install qpsolvers clarabel osqp piqp proxsuite)")
    if qpsolvers is not None:
        B = C.to_csr()
        P = sp.identity(2 * C.N, format="csc")
        qv = -Ud.ravel()
        for solver in ["clarabel", "piqp", "proxqp", "osqp"]:
            if solver not in qpsolvers.available_solvers:
                continue
            opts = dict(eps_abs=1e-10, eps_rel=1e-10) if solver in ("osqp", "proxqp") else {}
            if solver == "osqp":
                opts.update(max_iter=20000, polishing=True)
            t = time.perf_counter()
            sol = qpsolvers.solve_problem(qpsolvers.Problem(P, qv, B.tocsc(), d), solver=solver, **opts)
            dt = time.perf_counter() - t
            if sol.x is None:
                rows.append((solver, dt, np.inf, ref * np.nan))
                continue
            u = sol.x.reshape(-1, 2)
            lam = np.maximum(sol.z, 0) if sol.z is not None else np.zeros(C.m)
            rows.append((solver, dt, kkt_residual(C, Ud, d, u, lam), u))
    for name, dt, kkt, u in rows:
        print(f"  {name:28s} {1e3 * dt:9.1f} ms   KKT {kkt:8.1e}   |u - u_exact| {np.abs(u - ref).max():8.1e}")


if __name__ == "__main__":
    main()
