"""Cost per step of a small scene, by phase: the 1 m bottleneck of docs/validation.md (1 978 triangles, 90
people) with the variant "weidmann-push" (Weidmann's law, push 0.2, door capacity 1.9 /(m s)), run as
`femcrowd run` runs it (history.csv, frames every 10 s, summary), alternated with the same run on a baseline
checkout over `--repeat` rounds, each run in a fresh process (OPENBLAS with one thread). `--settings recommended`:
the recommended settings of benchmarks/peer.py instead (femcrowd/studies/recommended.py at FREE_SPEED, the
capacity of each exit's width), on `--scene` bottleneck or a hall of peer.py (`hall`: 100 people, `hall-1000`),
`--coarsen K` its cells K times the benchmark's; `--implicit CFL`: the implicit prediction at CFL times the
median cell's step (peer.py --implicit).

The phases are those of summary.json "timing" divided by the steps (transport: the step's set-up, the
prediction and the hooks before it; projection: the correction and the state update; recording: the rows of
history.csv and the loop's own work; output: frames, checkpoints, writing the rows); "rest" is the wall time of
the run's loop not booked to a phase (the model's step around the solver, the loop). The table gives the
medians over the rounds, in ms per step, with the process's CPU time per step (less sensitive to the other jobs
of a shared machine than the wall time) and the load average during the rounds.

    python benchmarks/small_scene.py --baseline /tmp/base               # a checkout: git worktree add /tmp/base REV
    python benchmarks/small_scene.py --baseline /tmp/base --end 10 --repeat 5
    python benchmarks/small_scene.py --settings recommended --scene hall --implicit 1 --repeat 3
"""

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from alternating import in_process, median, rounds  # this script's folder is on sys.path

PHASES = ("transport", "projection", "recording", "output")
#: the scenes of benchmarks/peer.py: (name, people)
SCENES = {"bottleneck": ("bottleneck", 90), "hall": ("hall", 100), "hall-1000": ("hall", 1000)}


def worker(end: float, settings: str, name: str, implicit: float, coarsen: float) -> None:
    """One run of the scene `name` with the settings to `end` (or until empty); prints its figures (JSON)."""
    from peer import scene

    import femcrowd
    from femcrowd.studies import recommended as r  # by attribute: a baseline checkout may predate MACRO

    directory = scene(*SCENES[name], coarsen)[0]   # made once, under peer.py's cache
    exits = femcrowd.load_case(directory)["boundary"]["exits"]
    overrides = ({**r.PUSHING, **r.door_capacity(exits, r.PUSH_CAPACITY)} if settings == "weidmann-push" else
                 {**r.MACRO, "velocity.speed": r.FREE_SPEED, **r.door_capacity(exits)})
    if implicit:
        overrides.update({"scheme.transport": "implicit", "time.cfl_quantile": 0.5, "time.cfl": implicit})
    with tempfile.TemporaryDirectory() as tmp:
        case = femcrowd.load_case(directory, {**overrides, "time.end": end})
        simulation = femcrowd.Simulation(case)
        cpu, wall = time.process_time(), time.perf_counter()
        result = simulation.run(Path(tmp) / "out")
        cpu, loop = time.process_time() - cpu, time.perf_counter() - wall
    timing, steps = result.summary["timing"], result.summary["steps"]
    print(json.dumps({"steps": steps, "cells": result.domain.ncells, "wall": loop / steps, "cpu": cpu / steps,
                      **{k: timing.get(k, 0.0) / steps for k in PHASES},
                      "rest": (loop - sum(timing.get(k, 0.0) for k in PHASES)) / steps}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="a femcrowd checkout to compare with (e.g. a git worktree of a revision)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the configurations")
    parser.add_argument("--end", type=float, default=200.0, help="time.end of the runs, s (the crowd is out at 58 s)")
    parser.add_argument("--settings", choices=["weidmann-push", "recommended"], default="weidmann-push")
    parser.add_argument("--scene", choices=list(SCENES), default="bottleneck")
    parser.add_argument("--implicit", type=float, default=0.0, metavar="CFL",
                        help="the implicit prediction at CFL x the median cell's step")
    parser.add_argument("--coarsen", type=float, default=1.0, metavar="K", help="a hall's cells K times peer.py's")
    parser.add_argument("--worker", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        end, settings, name, implicit, coarsen = args.worker
        return worker(float(end), settings, name, float(implicit), float(coarsen))
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    configs = ([("baseline", args.baseline, None)] if args.baseline else []) + [("this checkout", None, None)]
    from peer import scene

    scene(*SCENES[args.scene], args.coarsen)   # meshed once, before anything is timed
    worker_args = (args.end, args.settings, args.scene, args.implicit, args.coarsen)
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


if __name__ == "__main__":
    main()
