"""Cost per step of a small scene, by phase: the 1 m bottleneck of docs/validation.md (1 978 triangles, 90
people) with the variant "weidmann-push" (Weidmann's law, push 0.2, door capacity 1.9 /(m s)), run as
`femcrowd run` runs it (history.csv, frames every 10 s, summary), alternated with the same run on a baseline
checkout over `--repeat` rounds, each run in a fresh process (OPENBLAS with one thread). `--settings recommended`:
the recommended settings of benchmarks/peer.py instead (femcrowd/studies/recommended.py at FREE_SPEED, the
capacity of each exit's width), on `--scene` bottleneck or a hall of peer.py (`hall`: 100 people, `hall-1000`),
`--coarsen K` its cells K times the benchmark's; `--implicit CFL`: the implicit prediction at CFL times the
median cell's step (peer.py --implicit); `--settings fast`: the same with the fast step FAST_STEP (peer.py --fast).

The set-up (Simulation: scene, distance field, assembly) and the run together, in CPU seconds, are what
peer.py times (but loading the case). `--profile`: each run under cProfile on the thread's CPU clock
(cProfile.Profile(time.thread_time): the other jobs of the machine do not enter), and the share of the set-up and
the run of each part (PROFILED); the profiler's own cost inflates the many small calls, so the shares, not its
seconds, are the figures.

The phases are those of summary.json "timing" divided by the steps (transport: the step's set-up, the
prediction and the hooks before it; projection: the correction and the state update; recording: the rows of
history.csv and the loop's own work; output: frames, checkpoints, writing the rows); "rest" is the wall time of
the run's loop not booked to a phase (the model's step around the solver, the loop). The table gives the
medians over the rounds, in ms per step, with the process's CPU time per step (less sensitive to the other jobs
of a shared machine than the wall time) and the load average during the rounds.

    python benchmarks/small_scene.py --baseline /tmp/base               # a checkout: git worktree add /tmp/base REV
    python benchmarks/small_scene.py --baseline /tmp/base --end 10 --repeat 5
    python benchmarks/small_scene.py --settings recommended --scene hall --implicit 1 --repeat 3
    python benchmarks/small_scene.py --settings recommended --scene hall --coarsen 2 --implicit 1 --profile
    python benchmarks/small_scene.py --baseline /tmp/base --settings fast --scene hall --coarsen 2 --profile
"""

import argparse
import cProfile
import json
import os
import pstats
import tempfile
import time
from pathlib import Path

from alternating import in_process, median, rounds  # this script's folder is on sys.path

PHASES = ("transport", "projection", "recording", "output")
#: the scenes of benchmarks/peer.py: (name, people)
SCENES = {"bottleneck": ("bottleneck", 90), "hall": ("hall", 100), "hall-1000": ("hall", 1000)}
#: the parts of a run in the profile: label -> the functions (file, name) whose largest cumulative time it is
PROFILED = {
    "set-up (scene, mesh, distance, assembly)": [("driver/run.py", "__init__")],
    "of which finding the BLAS and OpenMP pools (threadpoolctl)": [("linalg/threads.py", "thread_limit")],
    "of which reading the mesh": [("mesh/domain.py", "load_domain")],
    "of which the eikonal fields": [("mesh/distance.py", "solve_each")],
    "of which the speed laws' constants": [("macro/speed_law.py", "__init__")],
    "route choice (re-solved when due)": [("macro/velocity.py", "route")],
    "transport (MacroSolver._predict)": [("macro/solver.py", "_predict")],
    "of which the rates (speed law)": [("macro/transport/implicit.py", "speeds")],
    "of which the flow order's solve": [("macro/transport/flow_order.py", "solve")],
    "of which the doors' cap": [("mesh/capacity.py", "limit")],
    "projection and state update (_correct_step)": [("macro/solver.py", "_correct_step")],
    "of which METIS's ordering (once a run)": [("macro/projection/solvers.py", "metis_order")],
    "of which the warm start's first update": [("macro/projection/warm_start.py", "first_update")],
    "of which the factorisations and solves on S": [("macro/projection/solvers.py", "solve")],
    "of which the doors' rows (room, report)": [("mesh/capacity.py", "room"), ("mesh/capacity.py", "report")],
    "of which the measurements (after the step)": [("driver/measurements.py", "after_step")],
    "the rows of history.csv (invariants)": [("driver/macro_model.py", "row")],
    "frames (and writing the rows)": [("driver/sink.py", "frame")],
    "checkpoints": [("driver/sink.py", "checkpoint")],
}


def shares(profile) -> dict:
    """The share of the profiled CPU time of each part of PROFILED, and the rest (the loop, the step's
    bookkeeping, the empty check, door changes)."""
    stats = pstats.Stats(profile).stats   # (file, line, name) -> (calls, primitive calls, own, cumulative, callers)
    total = sum(own for _, _, own, _, _ in stats.values())

    def cumulative(where, name):
        return max((v[3] for (f, _, n), v in stats.items() if n == name and f.endswith(where)), default=0.0)

    found = {label: sum(cumulative(*f) for f in functions) / total for label, functions in PROFILED.items()}
    found["the rest (loop, step bookkeeping, empty check, door changes)"] = \
        1.0 - sum(v for k, v in found.items() if not k.startswith("of which"))
    return found


def worker(end: float, settings: str, name: str, implicit: float, coarsen: float, profile: bool) -> None:
    """One run of the scene `name` with the settings to `end` (or until empty); prints its figures (JSON)."""
    from peer import scene

    import femcrowd
    from femcrowd.studies import recommended as r  # by attribute: a baseline checkout may predate MACRO

    directory = scene(*SCENES[name], coarsen)[0]   # made once, under peer.py's cache
    exits = femcrowd.load_case(directory)["boundary"]["exits"]
    overrides = ({**r.PUSHING, **r.door_capacity(exits, r.PUSH_CAPACITY)} if settings == "weidmann-push" else
                 {**(r.FAST if settings == "fast" else r.MACRO), "velocity.speed": r.FREE_SPEED,
                  **r.door_capacity(exits)})
    if implicit:
        overrides.update({"scheme.transport": "implicit", "time.cfl_quantile": 0.5, "time.cfl": implicit})
    profiler = cProfile.Profile(time.thread_time) if profile else None
    with tempfile.TemporaryDirectory() as tmp:
        case = femcrowd.load_case(directory, {**overrides, "time.end": end})
        if profiler:
            profiler.enable()
        start = time.process_time()
        simulation = femcrowd.Simulation(case)
        cpu, wall = time.process_time(), time.perf_counter()
        result = simulation.run(Path(tmp) / "out")
        cpu, loop, setup = time.process_time() - cpu, time.perf_counter() - wall, cpu - start
        if profiler:
            profiler.disable()
    timing, steps = result.summary["timing"], result.summary["steps"]
    print(json.dumps({"steps": steps, "cells": result.domain.ncells, "wall": loop / steps, "cpu": cpu / steps,
                      **{k: timing.get(k, 0.0) / steps for k in PHASES},
                      "rest": (loop - sum(timing.get(k, 0.0) for k in PHASES)) / steps,
                      "setup": setup, "total": setup + cpu, **(shares(profiler) if profiler else {})}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="a femcrowd checkout to compare with (e.g. a git worktree of a revision)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the configurations")
    parser.add_argument("--end", type=float, default=200.0, help="time.end of the runs, s (the crowd is out at 58 s)")
    parser.add_argument("--settings", choices=["weidmann-push", "recommended", "fast"], default="weidmann-push")
    parser.add_argument("--scene", choices=list(SCENES), default="bottleneck")
    parser.add_argument("--implicit", type=float, default=0.0, metavar="CFL",
                        help="the implicit prediction at CFL x the median cell's step")
    parser.add_argument("--coarsen", type=float, default=1.0, metavar="K", help="a hall's cells K times peer.py's")
    parser.add_argument("--profile", action="store_true", help="the share of each part of the run (cProfile)")
    parser.add_argument("--worker", nargs=6, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        end, settings, name, implicit, coarsen, profile = args.worker
        return worker(float(end), settings, name, float(implicit), float(coarsen), profile == "1")
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    configs = ([("baseline", args.baseline, None)] if args.baseline else []) + [("this checkout", None, None)]
    from peer import scene

    scene(*SCENES[args.scene], args.coarsen)   # meshed once, before anything is timed
    worker_args = (args.end, args.settings, args.scene, args.implicit, args.coarsen, int(args.profile))
    runs = rounds(configs, args.repeat, lambda code, _: in_process(__file__, worker_args, code, env))
    load = os.getloadavg()[1]
    first = runs[configs[0][0]][0]
    step = f", implicit cfl {args.implicit:g}" if args.implicit else ""
    print(f"{args.scene}, {args.settings}{step}: {first['cells']} triangles, {first['steps']} steps; medians of "
          f"{args.repeat} alternated runs, load average {load:.1f} (5 min) at the end")
    print("| phase, ms per step | " + " | ".join(name for name, _, _ in configs) + " |")
    print("|---|" + "---:|" * len(configs))
    for key in (*PHASES, "rest", "wall", "cpu"):
        label = {"wall": "whole step (wall)", "cpu": "whole step (CPU)"}.get(key, key)
        print(f"| {label} | " + " | ".join(f"{1e3 * median(runs[name], key):.3f}" for name, _, _ in configs) + " |")
    for key, label in (("setup", "set-up (CPU, s)"), ("total", "set-up and run (CPU, s)")):
        print(f"| {label} | " + " | ".join(f"{median(runs[name], key):.3f}" for name, _, _ in configs) + " |")
    if args.profile:
        print("\n| share of the set-up and run's CPU (cProfile) | " + " | ".join(name for name, _, _ in configs) + " |")
        print("|---|" + "---:|" * len(configs))
        for key in first:
            if key in PROFILED or key.startswith("the rest"):
                print(f"| {key} | " + " | ".join(f"{median(runs[name], key):.0%}" for name, _, _ in configs) + " |")


if __name__ == "__main__":
    main()
