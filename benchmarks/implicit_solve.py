"""CPU time per step of the linearly implicit LWR prediction (``scheme.transport = "implicit"`` with a speed law),
against a checkout of femcrowd before its solve in the order of the flow (docs/performance.md, "Larger steps:
the implicit prediction").

Scenes: the 1 m bottleneck of docs/validation.md on the plan's mesh and two refinements down (about 2 000 and
32 000 triangles) and the 40 x 30 m hall of benchmarks/peer.py with 1 000 people (23 000 triangles), with the
variant weidmann-push of the recommended settings (Weidmann's law, push 0.2, slip walls, door capacity 1.9 /(m s))
and the implicit prediction at `--cfl` times the median cell's step. Each run (a fresh process; with
``--baseline DIR``, e.g. ``git worktree add /tmp/base 96a1f94``, the same run on that checkout, in alternated
rounds) takes 20 steps to bring the crowd to the doors, then times `--steps` steps: the process's CPU seconds per
step of the transport phase (the prediction) and of the whole step.

    python benchmarks/implicit_solve.py --steps 10 --repeat 1
    python benchmarks/implicit_solve.py --baseline /tmp/base
"""

import argparse
import json
import math
import time

import peer  # this script's folder is on sys.path: the scenes of the peer benchmark
from alternating import arguments, in_process, median, rounds

#: the variant weidmann-push, written out (not imported: the --baseline checkout may name its settings otherwise)
SETTINGS = {"velocity.speed_law": "weidmann", "velocity.push": 0.2, "velocity.walls": "slip"}
CAPACITY = 1.9

#: (label, scene, people, mesh.refine)
SCENES = [("bottleneck", "bottleneck", 90, 0), ("bottleneck", "bottleneck", 90, 2), ("hall", "hall", 1000, 0)]


def worker(index, cfl, steps):
    """Time `steps` steps of scene `index` after 20; print the CPU seconds per step (JSON)."""
    import femcrowd

    _, name, people, refine = SCENES[int(index)]
    directory = peer.scene(name, int(people))[0]
    exits = femcrowd.load_case(directory)["boundary"]["exits"]
    case = femcrowd.load_case(directory, {**SETTINGS, "boundary.capacity": {door: CAPACITY for door in exits},
                                          "scheme.transport": "implicit",
                                          "time.cfl_quantile": 0.5, "time.cfl": float(cfl), "mesh.refine": refine})
    model = femcrowd.Simulation(case).model
    for _ in range(20):
        model.step(math.inf)
    timers = model.solver.timers
    before, cpu = dict(timers.items()), time.process_time()
    for _ in range(int(steps)):
        model.step(math.inf)
    cpu = (time.process_time() - cpu) / int(steps)
    # the transport phase's share of the step's wall time, applied to its CPU time
    share = (timers["transport"] - before["transport"]) / sum(v - before.get(k, 0.0) for k, v in timers.items())
    print(json.dumps({"step": cpu, "transport": share * cpu, "cells": model.domain.ncells}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cfl", type=float, default=1.0, help="time.cfl on the median cell's step")
    args = arguments(parser, "a checkout of femcrowd before the flow order (same rounds)")
    if args.worker:
        return worker(*args.worker)
    configs = ([("before", args.baseline, None)] if args.baseline else []) + [("flow order", None, None)]
    print("| scene | triangles | configuration | prediction (CPU ms/step) | whole step (CPU ms/step) |")
    print("|---|---:|---|---:|---:|")
    for index, (label, name, people, _) in enumerate(SCENES):
        peer.scene(name, people)   # meshed before anything is timed
        runs = rounds(configs, args.repeat, lambda code, _: in_process(__file__, (index, args.cfl, args.steps), code))
        for config, _, _ in configs:
            found = runs[config]
            print(f"| {label} | {found[0]['cells']} | {config} | {1e3 * median(found, 'transport'):.2f} | "
                  f"{1e3 * median(found, 'step'):.2f} |", flush=True)


if __name__ == "__main__":
    main()
