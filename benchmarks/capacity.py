"""Cost per step of a door with a capacity against the same case without one, on the hall of benchmarks/scale.py.

Scene: the 20 m x 15 m hall with a 2 m door in the wall x = 20, U towards the door at 1 m/s, crowd at
density 1 within 7 m of the door and 0.85 elsewhere beyond x = 3 (a large saturated zone from the first
step, pushing on the door). "free": the door as in the paper (p = 0 there); "capped": the same door with
``[boundary.capacity] exit = C`` (default 1: the flow of a saturated crowd at its desired speed, below what
the pressure pushes through it, so the door is at capacity and its nodes are in the projection at every
step). With ``--baseline DIR`` (a checkout of femcrowd before door capacities, e.g. ``git worktree add
/tmp/base HEAD~1``) the free door also runs on that code, in the same rounds.

Every configuration runs in its own process (femcrowd.load_case + femcrowd.Simulation, femcrowd's own
thread settings: one BLAS thread inside the run, as `femcrowd run` does), `--steps` steps after 3 warm-up
steps, and reports the median step; the configurations alternate over `--repeat` rounds so that a slow
period of the machine hits them all, and the table gives the median over the rounds and the ratio to the
free door.

    python benchmarks/capacity.py                      # 10^4 and 10^5 triangles
    python benchmarks/capacity.py --sizes 1e4 --repeat 5 --baseline /tmp/base
"""

import argparse
import json
import tempfile
from pathlib import Path

from alternating import arguments, by_size, in_process, median, timed_steps  # this script's folder is on sys.path
from scale import DENSITY, mesh_file  # the hall of benchmarks/scale.py


def case_text(mesh, capacity):
    """case.toml of the hall, its door capped at `capacity` (None: free)."""
    cap = f"capacity = {{ exit = {capacity!r} }}\n" if capacity is not None else ""
    return (f'[mesh]\nfile = "{mesh}"\n[boundary]\nexits = ["exit"]\n{cap}[initial]\ndensity = "{DENSITY}"\n'
            f'[time]\nend = 1e9\n[output]\nevery = 1e9\n')


def worker(target, capacity, steps):
    """Run `steps` steps (after 3 warm-up steps) of the hall; print the median step and the phases (JSON)."""
    import femcrowd

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "case.toml").write_text(case_text(mesh_file(target), capacity))
        model = femcrowd.Simulation(femcrowd.load_case(tmp)).model
        step, timers, infos = timed_steps(model, steps)
    at_capacity = sum(info.doors is not None and info.doors["exit"][1] > 0 for info in infos)
    print(json.dumps({"step": step, "cells": model.domain.ncells, "at_capacity": at_capacity, **timers}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e4, 1e5])
    parser.add_argument("--capacity", type=float, default=1.0, help="the door's capacity, rho_max x m/s per metre")
    args = arguments(parser, "a checkout of femcrowd before door capacities (free door, same rounds)")
    if args.worker:
        capacity = None if args.worker[1] == "None" else float(args.worker[1])
        return worker(float(args.worker[0]), capacity, int(args.worker[2]))
    configs = ([("baseline (free)", args.baseline, None)] if args.baseline else []) + \
        [("free", None, None), (f"capped at {args.capacity:g}", None, args.capacity)]
    print("| triangles | configuration | step (median) | transport | projection | steps at capacity | "
          "step / free |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for runs in by_size(args.sizes, configs, args.repeat,
                        lambda target, code, capacity: in_process(__file__, (target, capacity, args.steps), code)):
        free = median(runs["free"], "step")
        for name, _, _ in configs:
            step = median(runs[name], "step")
            print(f"| {runs[name][0]['cells']} | {name} | {1e3 * step:.2f} ms | "
                  f"{1e3 * median(runs[name], 'transport'):.2f} ms | {1e3 * median(runs[name], 'projection'):.2f} ms | "
                  f"{runs[name][0]['at_capacity']}/{args.steps} | {step / free:.3f} |", flush=True)


if __name__ == "__main__":
    main()
