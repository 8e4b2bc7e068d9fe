"""Cost per step of a small scene, by phase: the 1 m bottleneck of docs/validation.md (1 978 triangles, 90
people) with the variant "weidmann-push" (Weidmann's law, push 0.2, door capacity 1.9 /(m s)), run as
`femcrowd run` runs it (history.csv, frames every 10 s, summary), alternated with the same run on a baseline
checkout over `--repeat` rounds, each run in a fresh process (OPENBLAS with one thread).

The phases are those of summary.json "timing" divided by the steps (transport: the step's set-up, the
prediction and the hooks before it; projection: the correction and the state update; recording: the rows of
history.csv and the loop's own work; output: frames, checkpoints, writing the rows); "rest" is the wall time of
the run's loop not booked to a phase (the model's step around the solver, the loop). The table gives the
medians over the rounds, in ms per step, with the process's CPU time per step (less sensitive to the other jobs
of a shared machine than the wall time) and the load average during the rounds.

    python benchmarks/small_scene.py --baseline /tmp/base               # a checkout: git worktree add /tmp/base REV
    python benchmarks/small_scene.py --baseline /tmp/base --end 10 --repeat 5
"""

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from alternating import in_process, median, rounds  # this script's folder is on sys.path

PHASES = ("transport", "projection", "recording", "output")


def worker(end: float) -> None:
    """One run of the 1 m bottleneck (weidmann-push) to `end` (or until empty); prints its figures (JSON)."""
    import femcrowd
    from femcrowd.studies.recommended import PUSH_CAPACITY, PUSHING, door_capacity
    from femcrowd.studies.validation import scene

    with tempfile.TemporaryDirectory() as tmp:
        case = femcrowd.load_case(scene(1.0, Path(tmp)),
                                  {**PUSHING, **door_capacity(["exit"], PUSH_CAPACITY), "time.end": end})
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
    parser.add_argument("--worker", nargs=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(float(args.worker[0]))
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    configs = ([("baseline", args.baseline, None)] if args.baseline else []) + [("this checkout", None, None)]
    runs = rounds(configs, args.repeat, lambda code, _: in_process(__file__, (args.end,), code, env))
    load = os.getloadavg()[1]
    first = runs[configs[0][0]][0]
    print(f"1 m bottleneck, weidmann-push: {first['cells']} triangles, {first['steps']} steps; medians of "
          f"{args.repeat} alternated runs, load average {load:.1f} (5 min) at the end")
    print("| phase, ms per step | " + " | ".join(name for name, _, _ in configs) + " |")
    print("|---|" + "---:|" * len(configs))
    for key in (*PHASES, "rest", "wall", "cpu"):
        label = {"wall": "whole step (wall)", "cpu": "whole step (CPU)"}.get(key, key)
        print(f"| {label} | " + " | ".join(f"{1e3 * median(runs[name], key):.3f}" for name, _, _ in configs) + " |")


if __name__ == "__main__":
    main()
