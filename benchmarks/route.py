"""Cost of the route choice (velocity.route = "congestion", route_every = 1 s) against shortest paths, on a hall
with two doors.

Scene: the 20 m x 15 m hall of benchmarks/scale.py with a 2 m door in the wall x = 20 and a 1 m door in the
wall x = 0, the recommended settings (Weidmann's law, push 0.2, rho_max 5.4 persons/m^2, 1.3 m/s) and
3 persons/m^2 in the strip 2 m < x < 8 m, near the narrow door: the routes change as its queue grows. The doors
(`--doors`): both with a capacity of 1.9 persons/(m s) (default; a route is the walking distance, solved once,
and the waits), or free (no capacity: every route solves Hughes' eikonal equation for both doors), or both
kinds, one table each. Each configuration runs `--seconds` of simulated time (3 warm-up steps first) in its own
process, the configurations alternating over `--repeat` rounds; the table gives the medians over the rounds of
the wall time of the steps, the route phase's share of it, the ratio to shortest paths, and that ratio in each
round (the noise of the shared machine).

    python benchmarks/route.py                      # 10^4 and 10^5 triangles, doors with a capacity
    python benchmarks/route.py --sizes 1e4 --repeat 5 --doors capacity free
"""

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

from alternating import by_size, in_process, median  # this script's folder is on sys.path
from scale import mesh_file

HALL = """size = {size:.6g}
[outer]
points = [[0, 0], [20, 0], [20, 15], [0, 15]]
[[exits]]
name = "wide"
from = [20, 6.5]
to = [20, 8.5]
[[exits]]
name = "narrow"
from = [0, 7]
to = [0, 8]
"""


#: the doors' capacities: "capacity" (1.9 persons/(m s) each: a route is the walking distance, solved once, and
#: the waits) or "free" (none: a route solves Hughes' eikonal equation for each door)
CAPACITY = {"capacity": "[boundary.capacity]\nwide = 1.9\nnarrow = 1.9\n", "free": ""}


def case_text(mesh, route, doors):
    return (f'[mesh]\nfile = "{mesh}"\n[boundary]\nexits = ["wide", "narrow"]\n'
            f'{CAPACITY[doors]}[model]\nrho_max = 5.4\n'
            f'[velocity]\nspeed = 1.3\nspeed_law = "weidmann"\npush = 0.2\nroute = "{route}"\nroute_every = 1.0\n'
            '[initial]\ndensity = "3.0 * (x > 2) * (x < 8)"\n[time]\nend = 1e9\n[output]\nevery = 1e9\n')


def worker(target, route, seconds, doors):
    """Step `seconds` of simulated time (after 3 warm-up steps); print the wall time and the phases (JSON)."""
    import femcrowd

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "case.toml").write_text(case_text(mesh_file(target, HALL, "two_doors"), route, doors))
        model = femcrowd.Simulation(femcrowd.load_case(tmp), limits=None).model
        for _ in range(3):
            model.step(math.inf)
        before, end, steps = dict(model.solver.timers.items()), model.t + seconds, 0
        tic = time.perf_counter()
        while model.t < end:
            model.step(end)
            steps += 1
        wall = time.perf_counter() - tic
    phases = {name: value - before.get(name, 0.0) for name, value in model.solver.timers.items()}
    print(json.dumps({"wall": wall, "steps": steps, "cells": model.domain.ncells, **phases}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e4, 1e5])
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per run")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the configurations")
    parser.add_argument("--doors", nargs="+", choices=list(CAPACITY), default=["capacity"],
                        help="the doors: with a capacity of 1.9 persons/(m s) (default) or free (none: Hughes' "
                        "eikonal equation re-solved for each door at every route); both: two tables")
    parser.add_argument("--worker", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(float(args.worker[0]), args.worker[1], float(args.worker[2]), args.worker[3])
    for doors in args.doors:
        table(args, doors)


def table(args, doors):
    """The table of one kind of doors: shortest paths and the route choice alternated, at each size."""
    configs = [("shortest", None, "shortest"), ("congestion", None, "congestion")]
    print(f"\ndoors: {doors}\n")
    print("| triangles | route | steps | wall (median) | route phase | route share | wall / shortest | per round |")
    print("|---:|---|---:|---:|---:|---:|---:|---|")
    for runs in by_size(args.sizes, configs, args.repeat,
                        lambda target, code, route: in_process(__file__, (target, route, args.seconds, doors))):
        shortest = median(runs["shortest"], "wall")
        for name, _, _ in configs:
            for run in runs[name]:
                run.setdefault("route", 0.0)
                run["share"] = run["route"] / run["wall"]
            wall = median(runs[name], "wall")
            rounds = ", ".join(f"{run['wall'] / other['wall']:.2f}" for run, other in zip(runs[name], runs["shortest"]))
            print(f"| {runs[name][0]['cells']} | {name} | {runs[name][0]['steps']} | {wall:.2f} s | "
                  f"{median(runs[name], 'route'):.2f} s | {100 * median(runs[name], 'share'):.1f} % | "
                  f"{wall / shortest:.2f} | {rounds} |", flush=True)


if __name__ == "__main__":
    main()
