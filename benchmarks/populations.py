"""Cost per step of k populations against one, on the benchmark hall of benchmarks/scale.py.

Scene: the 20 m x 15 m hall with a 2 m door in the wall x = 20, U towards the door at 1 m/s, crowd at
density 1 within 7 m of the door and 0.85 elsewhere beyond x = 3 (a large saturated zone from the first
step). k populations: the same crowd cut into k horizontal stripes, one population each, with the same
desired velocity: the total moves exactly as one population, so the projection is the same and the
difference is the cost of the populations (k transports and the split of the correction).

Every configuration runs in its own process (femcrowd.load_case + femcrowd.Simulation, OPENBLAS with one
thread), `--steps` steps after 3 warm-up steps, and reports the median step; the configurations
alternate over `--repeat` rounds so that a slow period of the machine hits them all, and the table gives
the median over the rounds. With ``--baseline DIR`` (a checkout of femcrowd, e.g. the commit this
feature started from: ``git worktree add /tmp/base16 a5b1ec9``) one population also runs on that code,
in the same rounds.

    python benchmarks/populations.py                          # 10^4 triangles, k = 1, 2, 4
    python benchmarks/populations.py --sizes 1e4 1e5 --baseline /tmp/base16
"""

import argparse
import json
import tempfile
from pathlib import Path

from alternating import arguments, in_process, median, rounds, timed_steps  # this script's folder is on sys.path
from scale import DENSITY, mesh_file  # the hall of benchmarks/scale.py


def case_text(mesh, k):
    """case.toml of the hall with the crowd in k populations (k = 1: [initial], as before populations)."""
    text = f'[mesh]\nfile = "{mesh}"\n[boundary]\nexits = ["exit"]\n[time]\nend = 1e9\n[output]\nevery = 1e9\n'
    if k == 1:
        return text + f'[initial]\ndensity = "{DENSITY}"\n'
    for i in range(k):
        stripe = f"(y >= {15 * i / k:.6g}) * (y < {15 * (i + 1) / k:.6g})" if i < k - 1 else f"(y >= {15 * i / k:.6g})"
        text += f'[populations.p{i}]\ndensity = "({DENSITY}) * {stripe}"\n'
    return text


def worker(target, k, steps):
    """Run `steps` steps (after 3 warm-up steps) of the hall with k populations; print the medians (JSON)."""
    import femcrowd

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "case.toml").write_text(case_text(mesh_file(target), k))
        model = femcrowd.Simulation(femcrowd.load_case(tmp)).model
        step, timers, _ = timed_steps(model, steps)
    print(json.dumps({"step": step, "cells": model.domain.ncells, **timers}))


def measure(code, target, k, steps):
    """One configuration in a fresh process on the femcrowd of `code` (a checkout, or None: this one)."""
    return in_process(__file__, (target, k, steps), code, {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e4])
    parser.add_argument("--populations", default="1,2,4")
    args = arguments(parser, "a checkout of femcrowd to time one population on (before/after)")
    if args.worker:
        return worker(float(args.worker[0]), int(args.worker[1]), int(args.worker[2]))
    ks = [int(k) for k in args.populations.split(",")]
    configs = ([("baseline", args.baseline, 1)] if args.baseline else []) + [(f"k = {k}", None, k) for k in ks]
    print("| triangles | configuration | step (median) | transport | projection + split | step / one population "
          "| bound 1 + 0.2 k |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for target in args.sizes:
        mesh_file(target)
        runs = rounds(configs, args.repeat, lambda code, k: measure(code, target, k, args.steps))
        one = median(runs["k = 1"], "step")
        for name, _, k in configs:
            step = median(runs[name], "step")
            bound = f"{1 + 0.2 * k:.1f}" if name != "baseline" else ""
            print(f"| {runs[name][0]['cells']} | {name} | {1e3 * step:.2f} ms | "
                  f"{1e3 * median(runs[name], 'transport'):.2f} ms | {1e3 * median(runs[name], 'projection'):.2f} ms | "
                  f"{step / one:.3f} | {bound} |", flush=True)


if __name__ == "__main__":
    main()
