"""Cost per step of the macro solver from 10^4 to 10^6 triangles.

Scene: a 20 m x 15 m hall with a 2 m door in the middle of the wall x = 20,
U = -grad d / |grad d| (distance to the door, unit speed), crowd at density 1
(saturated) within 7 m of the door and 0.85 elsewhere beyond x = 3: a large
saturated zone from the first step. Meshes are made once with gmsh
(femcrowd.mesh.floorplan.build_mesh) in benchmarks/.cache.

Every size runs in its own process (peak memory per size) and prints, per phase,
the median over the steps; the projection is compared, on the same saturated
system, with one Ruge-Stuben AMG + CG solve from scratch (set-up + solve to the
same tolerance, zero initial guess, the projection's AMG settings). The fitted exponent of the cost per step
is taken between the two largest sizes.

    python benchmarks/scale.py                      # sizes 1e4 1e5 1e6, 30 steps each
    python benchmarks/scale.py --sizes 1e4 1e5 --steps 20
    python benchmarks/scale.py --long               # the 10^6 hall until empty, end to end (femcrowd.run)
    python benchmarks/scale.py --long --long-size 1e5 --transport upwind --cfl 0.5
    python benchmarks/scale.py --long --capacity 1   # the same, its door capped at 1 (density x speed) per metre
    python benchmarks/scale.py --long --capacity 1 --long-size 2.5e5 --end 20 --counters   # the projection's counters

``--capacity C`` gives the door a capacity of C per metre and per second (units of rho_max x m/s: 1 is the
flow of a saturated crowd walking at its desired speed, without the pressure's push): benchmarks/capacity.py
compares the cost per step with and without it.
"""

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CACHE = Path(__file__).resolve().parent / ".cache"
HALL = """size = {size:.6g}
[outer]
points = [[0, 0], [20, 0], [20, 15], [0, 15]]
[[exits]]
name = "exit"
from = [20, 6.5]
to = [20, 8.5]
"""
AREA = 300.0
DENSITY = "where((x - 20)**2 + (y - 7.5)**2 < 49, 1.0, 0.85 * (x > 3))"


def mesh_file(target, plan_text=HALL, name="hall"):
    """The cached gmsh mesh of the 20 m x 15 m plan `plan_text` (its cell size a field {size}) with about `target`
    triangles (made on first use)."""
    from femcrowd.mesh.floorplan import build_mesh

    path = CACHE / f"{name}_{int(target)}.msh"
    if not path.exists():
        CACHE.mkdir(exist_ok=True)
        plan = path.with_suffix(".toml")
        plan.write_text(plan_text.format(size=math.sqrt(2.31 * AREA / target)))  # ~1.14 target triangles
        build_mesh(plan, path)
    return path


def peak_memory_gb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # ru_maxrss is in KiB on Linux


def one_size(target, steps, capacity=None):
    """All phases at one size; returns a dict of medians and totals (seconds)."""
    from femcrowd.case import Expression
    from femcrowd.driver.output import FrameSeries, triangle_frame
    from femcrowd.linalg.amg import amg_hierarchy, pcg, vcycle
    from femcrowd.macro import MacroSolver, MacroState
    from femcrowd.macro.velocity import ExitsVelocity
    from femcrowd.mesh import Boundary, load_domain

    path = mesh_file(target)
    out = {"target": target}
    tic = time.perf_counter()
    domain = load_domain(path, ["exit"])
    boundary = Boundary(domain, capacity=None if capacity is None else {"exit": capacity})
    exits = boundary.at(0.0)
    out["mesh_load"] = time.perf_counter() - tic
    out["triangles"] = domain.ncells
    tic = time.perf_counter()
    velocity = ExitsVelocity(domain, Expression("1"))
    velocity.cells(exits)
    out["distance"] = time.perf_counter() - tic
    print(f"{domain.ncells} triangles: load {out['mesh_load']:.1f} s, distance {out['distance']:.1f} s",
          file=sys.stderr, flush=True)
    state = MacroState.initial(Expression(DENSITY)(*domain.centroid.T, 0.0)[None], 1)
    tic = time.perf_counter()
    solver = MacroSolver(domain, boundary, [velocity], cfl=0.5)
    projection = solver.projection(exits)
    transport = solver.transports(state, exits)[0]
    out["assembly"] = time.perf_counter() - tic
    tic = time.perf_counter()
    solver.order(projection.A)  # else computed at the first factorisation
    out["ordering"] = time.perf_counter() - tic

    record = []
    mass0, worst = domain.area @ state.density, {"mass_error": 0.0, "max_density": 0.0, "min_density": 1.0,
                                                 "min_phi": 0.0}
    for k in range(steps):
        before, timers = state.density.copy(), dict(solver.timers.items())
        tic = time.perf_counter()
        result = solver.step(state)
        step = time.perf_counter() - tic
        record.append({**result.projection, "step": step,
                       "transport": solver.timers["transport"] - timers.get("transport", 0.0),
                       "projection": solver.timers["projection"] - timers.get("projection", 0.0)})
        mass = domain.area @ state.density
        worst["mass_error"] = max(worst["mass_error"], abs(mass + state.evacuated.sum() - mass0) / mass0)
        worst["max_density"] = max(worst["max_density"], float(state.rho.max()))
        worst["min_density"] = min(worst["min_density"], float(state.rho.min()))
        worst["min_phi"] = min(worst["min_phi"], float(state.p.min()))
        if k % 3 == 2 or k == steps - 1:  # the same saturated system solved from scratch by AMG
            S = projection.warm.active
            K = projection.A[S][:, S].tocsr()
            rho_tilde = transport.step(before, result.dt)[0]  # the step's prediction, again
            rhs = domain.area[S] * (rho_tilde[S] - 1.0)
            tic = time.perf_counter()
            ml = amg_hierarchy(K)
            setup = time.perf_counter() - tic
            _, its, ok = pcg(K, rhs, np.zeros(len(S)), lambda r: vcycle(ml, r),
                             projection.solver._threshold(K, S, projection.tol), maxiter=500)
            record[-1]["amg_fresh"] = time.perf_counter() - tic
            record[-1].update(amg_fresh_setup=setup, amg_fresh_iterations=its, amg_fresh_converged=ok)
        r = record[-1]
        print(f"step {k}: {r['step']:.3f} s, |S| {r['unknowns']}, active-set its {r['iterations']}, "
              f"CG its {r['linear_iterations']}, rebuilds {r['rebuilds']}, fresh AMG {r.get('amg_fresh', 0):.3f} s",
              file=sys.stderr, flush=True)
    matvec = []
    for _ in range(20):  # the floor of a transport step: one mat-vec with its prebuilt matrix
        tic = time.perf_counter()
        transport._update @ state.density
        matvec.append(time.perf_counter() - tic)
    out["matvec"] = float(np.median(matvec))
    with tempfile.TemporaryDirectory() as tmp:
        series = FrameSeries(Path(tmp), "solution")
        tic = time.perf_counter()
        fields = {"density": state.density, "pressure": state.p, "velocity": solver.velocity_field(state)}
        series.write(state.t, triangle_frame(domain, fields))
        out["output"] = time.perf_counter() - tic
        out["frame_mb"] = sum(f.stat().st_size for f in Path(tmp).glob("*.vtu")) / 2**20

    def median(key, rows=record):
        values = [r[key] for r in rows if key in r]
        return float(np.median(values)) if values else float("nan")

    sampled = [r for r in record if "amg_fresh" in r]
    out.update({key: median(key) for key in
                ("step", "transport", "projection", "detect", "predict", "active_set", "setup", "solve", "unknowns",
                 "linear_iterations", "rebuilds", "iterations")})
    warm = record[1:] or record  # the first step has no previous S to start from
    out["iterations_mean"] = float(np.mean([r["iterations"] for r in warm]))
    out["iterations_max"] = int(max(r["iterations"] for r in warm))
    out["iterations_cold"] = record[0]["iterations"]
    out["factorizations_mean"] = float(np.mean([r["factorizations"] for r in warm]))
    out["band_solves_mean"] = float(np.mean([r["band_solves"] for r in warm]))
    out["amg_fresh"] = median("amg_fresh", sampled)
    out["amg_fresh_setup"] = median("amg_fresh_setup", sampled)
    out["amg_fresh_iterations"] = median("amg_fresh_iterations", sampled)
    out["ratio"] = float(np.median([r["projection"] / r["amg_fresh"] for r in sampled]))
    out["ratio_max"] = float(np.max([r["projection"] / r["amg_fresh"] for r in sampled]))
    out["steps"], out["dt"] = steps, solver.stable_dt(state)
    out.update(worst)
    out["peak_gb"] = peak_memory_gb()
    return out


def counted_projections():
    """The projection counters of every macro step of this process (MacroStep.projection) and the CPU seconds of
    the step (step_cpu: transport and projection), appended to the list returned: MacroSolver.step is wrapped, the
    run itself is unchanged."""
    from femcrowd.macro import MacroSolver

    steps, step = [], MacroSolver.step

    def counted(self, *args, **kwargs):
        cpu = time.process_time()
        result = step(self, *args, **kwargs)
        steps.append({**result.projection, "step_cpu": time.process_time() - cpu})
        return result

    MacroSolver.step = counted
    return steps


def projection_phases(steps):
    """Sums and per-step means of the projection counters, split at the step of the largest saturated set: the
    queue growing (its front running into the oncoming crowd) and the queue draining."""
    keys = ("iterations", "factorizations", "band_solves", "rebuilds", "predict", "setup", "solve", "active_set",
            "step_cpu")
    peak = int(np.argmax([s["unknowns"] for s in steps])) + 1 if steps else 0
    out = {}
    for name, part in (("growing", steps[:peak]), ("draining", steps[peak:]), ("all", steps)):
        sums = {key: float(sum(s[key] for s in part)) for key in keys}
        out[name] = {"steps": len(part), "max_unknowns": max((s["unknowns"] for s in part), default=0),
                     **{f"{key} per step": sums[key] / max(len(part), 1) for key in keys},
                     **{f"{key} total": sums[key] for key in ("predict", "setup", "solve", "active_set", "step_cpu")}}
    return out


def long_run(target, transport, cfl, capacity=None, end=1000.0, counters=False):
    """The complete evacuation of the hall through the user path (femcrowd.run), timed end to end: it stops
    once less than time.empty_fraction of the crowd is inside (or at time `end`). counters: the projection's
    counters per phase of the run (projection_phases)."""
    from femcrowd import load_case, run
    from femcrowd.driver.reading import read_history

    steps = counted_projections() if counters else None
    path = mesh_file(target)
    case_dir = CACHE / (f"long_{int(target)}_{transport}_{cfl:g}" + (f"_c{capacity:g}" if capacity else "")
                        + (f"_end{end:g}" if end != 1000.0 else ""))
    case_dir.mkdir(parents=True, exist_ok=True)
    (case_dir / "case.toml").write_text(
        f'title = "benchmark hall, {int(target)} triangles"\n[mesh]\nfile = "{path}"\n'
        f'[boundary]\nexits = ["exit"]\n' + (f"capacity = {{ exit = {capacity!r} }}\n" if capacity else "") +
        f'[initial]\ndensity = "{DENSITY}"\n'
        f'[scheme]\ntransport = "{transport}"\n[time]\nend = {end!r}\ncfl = {cfl!r}\n[output]\nevery = 20.0\n')
    tic, cpu = time.perf_counter(), time.process_time()
    summary = run(load_case(case_dir), out=case_dir / "output", force=True).summary
    wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
    step_seconds = read_history(case_dir / "output" / "history.csv")["step_seconds"][1:]
    tenth = max(1, len(step_seconds) // 10)
    return {"triangles": summary["mesh"]["triangles"], "steps": summary["steps"], "wall": wall, "cpu": cpu,
            "projection_phases": None if steps is None else projection_phases(steps),
            "evacuation_time": summary["evacuation_time"], "simulated_time": summary["final_time"],
            "peak_gb": peak_memory_gb(), "timing": summary["timing"], "transport": transport, "cfl": cfl,
            "step_seconds": {"median": float(np.median(step_seconds)),
                             "first tenth": float(np.mean(step_seconds[:tenth])),
                             "last tenth": float(np.mean(step_seconds[-tenth:])), "max": float(step_seconds.max())},
            "mass_error": summary["max_mass_error"], "max_density": summary["max_density_ever"],
            "min_density": summary["min_density_ever"], "min_pressure": summary["min_pressure_ever"],
            "active_set_iterations": summary["active_set_iterations"],
            "evacuated_fraction": summary["evacuated"] / summary["initial_mass"], "capacity": capacity,
            "door": summary.get("doors", {}).get("exit")}


ROWS = [("triangles", "triangles", "{:.0f}"), ("mesh load [s]", "mesh_load", "{:.2f}"),
        ("distance field [s]", "distance", "{:.2f}"), ("operator assembly [s]", "assembly", "{:.2f}"),
        ("nested-dissection order, METIS [s]", "ordering", "{:.2f}"),
        ("transport step [ms]", "transport", "ms"), ("  one CSR mat-vec, same matrix [ms]", "matvec", "ms"),
        ("projection step [ms]", "projection", "ms"),
        ("  saturated-set detection [ms]", "detect", "ms"), ("  warm-start predictor [ms]", "predict", "ms"),
        ("  active-set bookkeeping [ms]", "active_set", "ms"),
        ("  linear set-up [ms]", "setup", "ms"), ("  linear solve [ms]", "solve", "ms"),
        ("  unknowns (cells in S)", "unknowns", "{:.0f}"), ("  active-set iterations (median)", "iterations", "{:.0f}"),
        ("  active-set iterations mean / max (warm-started steps)", None, None),
        ("  active-set iterations, cold first step", "iterations_cold", "{:.0f}"),
        ("  numeric factorisations per step, mean (warm-started steps)", "factorizations_mean", "{:.2f}"),
        ("  predictor band solves per step, mean (warm-started steps)", "band_solves_mean", "{:.2f}"),
        ("  CG iterations per step", "linear_iterations", "{:.0f}"),
        ("  new envelopes or AMG set-ups per step (median)", "rebuilds", "{:.0f}"),
        ("one fresh AMG solve [ms]", "amg_fresh", "ms"), ("  its set-up [ms]", "amg_fresh_setup", "ms"),
        ("  its CG iterations", "amg_fresh_iterations", "{:.0f}"),
        ("projection / fresh AMG (median)", "ratio", "{:.2f}"), ("projection / fresh AMG (max)", "ratio_max", "{:.2f}"),
        ("whole step [ms]", "step", "ms"), ("VTU frame write [s]", "output", "{:.2f}"),
        ("VTU frame size [MB]", "frame_mb", "{:.1f}"), ("peak memory [GB]", "peak_gb", "{:.2f}"),
        ("max mass error (relative)", "mass_error", "{:.1e}"), ("max density", "max_density", "{:.12f}"),
        ("min density", "min_density", "{:.1e}"), ("min pressure", "min_phi", "{:.1e}")]


def table(results, rows=ROWS, special=lambda r: f"{r['iterations_mean']:.2f} / {r['iterations_max']}"):
    """Markdown table: one column per size; a row without a key shows special(result)."""
    head = "| phase (median) | " + " | ".join(f"{r['target']:.0e}" for r in results) + " |"
    lines = [head, "|---|" + "---:|" * len(results)]
    for label, key, fmt in rows:
        if key is None:
            cells = [special(r) for r in results]
        elif fmt == "ms":
            cells = [f"{1e3 * r[key]:.2f}" for r in results]
        else:
            cells = [fmt.format(r[key]) for r in results]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def child(args):
    """Run this script in a new process (one size, or the long run) and parse its JSON line.

    OpenBLAS runs one thread unless the caller says otherwise: on a shared 2-core machine its
    threads (SuperLU, dense dot products) spin against the other processes and made the
    sparse-direct steps 2x and pyamg's own CG 10x slower.
    """
    env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
    done = subprocess.run([sys.executable, __file__, *args], check=True, capture_output=True, text=True, env=env)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6], help="target triangle counts")
    parser.add_argument("--steps", type=int, default=30, help="steps per size (medians over them)")
    parser.add_argument("--long", action="store_true", help="time the complete evacuation, end to end")
    parser.add_argument("--long-size", type=float, default=1e6, help="triangles of the --long run")
    parser.add_argument("--transport", default="implicit", help="scheme.transport of the --long run")
    parser.add_argument("--cfl", type=float, default=20.0, help="time.cfl of the --long run")
    parser.add_argument("--capacity", type=float, help="capacity of the door, per metre (rho_max x m/s)")
    parser.add_argument("--end", type=float, default=1000.0, help="time.end of the --long run (default: until empty)")
    parser.add_argument("--counters", action="store_true",
                        help="--long: the projection's counters and seconds, queue growing / draining")
    parser.add_argument("--one", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--long-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_size(args.one, args.steps, args.capacity)))
        return
    capped = ["--capacity", str(args.capacity)] if args.capacity else []
    long_args = ["--long-size", str(args.long_size), "--transport", args.transport, "--cfl", str(args.cfl), *capped,
                 "--end", str(args.end), *(["--counters"] if args.counters else [])]
    if args.long_child:
        print(json.dumps(long_run(args.long_size, args.transport, args.cfl, args.capacity, args.end, args.counters)))
        return
    if args.long:
        mesh_file(args.long_size)   # meshing is not part of the timing
        r = child(["--long-child", *long_args])
        until = "stopped at" if r["evacuation_time"] is None else "empty at"
        print(f"{r['triangles']} triangles, {r['transport']} transport at cfl {r['cfl']:g}: {until} "
              f"t = {r['evacuation_time'] or r['simulated_time']:.1f} s after {r['steps']} steps, "
              f"{r['wall']:.0f} s end to end "
              f"({r['wall'] / 60:.1f} min, {r['cpu']:.0f} s of CPU), peak memory {r['peak_gb']:.2f} GB")
        print(json.dumps(r, indent=1))
        return
    results = []
    for size in args.sizes:
        for mesh in [mesh_file(size)]:  # meshing is not part of any timing
            assert mesh.exists()
        results.append(child(["--one", str(size), "--steps", str(args.steps), *capped]))
        print(f"size {size:.0e} done: {results[-1]['triangles']} triangles", file=sys.stderr)
    print(table(results))
    if len(results) >= 2:
        (a, b) = results[-2], results[-1]
        ratio = math.log(b["triangles"] / a["triangles"])
        for key in ("step", "transport", "projection"):
            print(f"fitted exponent of the {key} cost between {a['triangles']} and {b['triangles']} triangles: "
                  f"{math.log(b[key] / a[key]) / ratio:.2f}")


if __name__ == "__main__":
    main()
