"""Benchmark of the disc model: a room evacuation through one door, cost per jammed step.

    python benchmarks/micro.py                       # N = 2000 (20 x 20 room, 2 m door), 300 steps
    python benchmarks/micro.py --n 500 --steps 100
    python benchmarks/micro.py --scale               # N = 500, 2000, 8000, 20000, each in its own process
    python benchmarks/micro.py --against /tmp/base15 # also the femcrowd of another checkout, alternately

A step is jammed when it has at least as many active contacts as discs. Prints the median and p90 ms
per jammed step, factorisations per step, the largest overlap (in radii) and certified relative
objective gap over all steps, and, on 10 sampled jammed steps, the objective gap and the velocity
difference against a tight solve of the same projection (gap_tol = 1e-12). One BLAS thread unless
--threads says otherwise, like femcrowd run. Reference: cromosim needs about 58 ms/step (cvxopt) and
100 ms/step (Uzawa) for N = 2000 in this room, with overlaps of 0.24-0.49 m.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(os.environ.get("FEMCROWD_SOURCE", Path(__file__).resolve().parents[1]))))

from femcrowd.micro import MicroSimulation  # noqa: E402
from femcrowd.micro.contacts import point_segment_distance  # noqa: E402
from femcrowd.micro.projection import project  # noqa: E402


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


def measure(n, steps, radius=0.2, tau=0.05, seed=0, samples=10) -> dict:
    """One evacuation of n discs for `steps` steps: per-step costs and accuracy, and tight re-solves of
    `samples` jammed projections."""
    L, walls, exits = scenario(n)
    q = hex_crowd(L, n, radius, seed=seed)
    sim = MicroSimulation(q, radius, walls, exits, towards_exits(exits, radius), tau)
    jammed, facts, overlap, gap, change, checks = [], [], 0.0, 0.0, 0.0, []
    every = max(1, steps // samples)
    for k in range(steps):
        sample = k % every == 0 and len(checks) < samples and sim.contacts.cl is not None
        if sample:   # the projection this step will solve, to solve it again tightly
            C, lam0, U = sim.contacts.constraints(sim.q, sim.r), sim.contacts.lam.copy(), sim.desired_velocity()
            d = np.maximum(C.D, -sim._recover) / tau
        info = sim.step()
        facts.append(info.factorizations)
        overlap = max(overlap, getattr(info, "overlap_r", info.max_overlap / radius))
        gap, change = max(gap, getattr(info, "gap", 0.0)), max(change, getattr(info, "change", 0.0))
        if info.contacts >= info.count + info.evacuated_now:
            jammed.append(info.seconds)
            if sample and hasattr(info, "gap"):
                fast, tight = project(C, U, d, lam0=lam0), project(C, U, d, lam0=lam0, gap_tol=1e-12)
                cost = [0.5 * float(np.sum((r.u - U) ** 2)) for r in (fast, tight)]
                checks.append(((cost[0] - cost[1]) / cost[1], float(np.abs(fast.u - tight.u).max())))
    ms = 1e3 * np.array(jammed) if jammed else np.full(1, np.nan)
    return {"n": n, "steps": steps, "jammed": len(jammed), "median_ms": float(np.median(ms)),
            "p90_ms": float(np.percentile(ms, 90)), "factorizations": float(np.mean(facts)),
            "max_overlap_r": overlap, "max_gap": gap, "max_change": change,
            "tight_gap": max((c[0] for c in checks), default=float("nan")),
            "tight_velocity": max((c[1] for c in checks), default=float("nan")),
            "peak_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


def child(n, steps, threads, source=None) -> dict:
    """measure() in a new process (its own peak memory), on this checkout's femcrowd or another's."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": str(threads), "OMP_NUM_THREADS": str(threads)}
    if source is not None:
        env["FEMCROWD_SOURCE"] = str(source)
    out = subprocess.run([sys.executable, __file__, "--child", "--n", str(n), "--steps", str(steps)],
                         check=True, capture_output=True, text=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def line(r, label=""):
    return (f"{label}N = {r['n']}: {r['jammed']} of {r['steps']} steps jammed, median {r['median_ms']:.1f} ms "
            f"(p90 {r['p90_ms']:.1f}) per jammed step, {r['factorizations']:.1f} factorisations per step; "
            f"max overlap {r['max_overlap_r']:.1e} r, max gap {r['max_gap']:.1e}, change {r['max_change']:.1e} m/s; "
            f"against a tight solve: gap {r['tight_gap']:.1e}, velocity {r['tight_velocity']:.1e} m/s; "
            f"peak {r['peak_gb']:.2f} GB")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=2000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--scale", action="store_true", help="N = 500, 2000, 8000, 20000 (200 steps from 8000 on)")
    ap.add_argument("--against", type=Path, help="another femcrowd checkout, run alternately with this one")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds with --against")
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads (femcrowd run's default: 1)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(measure(args.n, args.steps)))
        return
    if args.scale:
        results = [child(n, args.steps if n <= 2000 else 200, args.threads) for n in (500, 2000, 8000, 20000)]
        for r in results:
            print(line(r))
        a, b = results[1], results[-1]
        print(f"fitted exponent of the jammed-step cost from N = {a['n']} to {b['n']}: "
              f"{math.log(b['median_ms'] / a['median_ms']) / math.log(b['n'] / a['n']):.2f} "
              f"(N = 20000 / N = 2000: {b['median_ms'] / a['median_ms']:.1f}x)")
        return
    for k in range(args.rounds if args.against else 1):
        now = child(args.n, args.steps, args.threads)
        print(line(now, f"round {k + 1}, this checkout:   "), flush=True)
        if args.against:
            before = child(args.n, args.steps, args.threads, args.against)
            print(line(before, f"round {k + 1}, {args.against}: "), flush=True)
            print(f"round {k + 1}: ratio of the median jammed step {now['median_ms'] / before['median_ms']:.2f}")


if __name__ == "__main__":
    main()
