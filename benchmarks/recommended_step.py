"""The recommended step chosen by accuracy (issue 38): the explicit LWR fluxes at cfl 1 against the linearly implicit
predictions on the median cell's step (implicit, the flux q_e rho~_K f(rho_L), at cfl 1 and 2; implicit-godunov, the
explicit fluxes' rates frozen at the step's start, at cfl 1, 2 and 4), on the same mesh, with the recommended settings
(femcrowd/studies/recommended.py: Predtechenskii and Milinskii's law at the case's speed and no push, slip walls, the
capacity of its width on every door, exits and interior doors alike; the step of each series instead of STEP).

Per scene, mesh and series: cells, steps, CPU seconds, the times at which 50, 90, 99 % and all but half a person
are out, and each door's flow (persons/s while 20 to 80 % of the persons through it have passed), each as its
difference in % from the explicit step on the same mesh, the step's own error (the mesh's is larger and the
same for every series). Scenes: those of frontier.py (the 1 m bottleneck of `femcrowd validate` at the free speed
of the law, the 40 x 30 m hall of benchmarks/peer.py with 100 and 1 000 people), cases/route-queues,
cases/route-choice, and RiMEA test 12 (a door inside: the corridor). Serial, one run at a time.

    python benchmarks/recommended_step.py --scenes route-choice --levels 1
    python benchmarks/recommended_step.py --scenes route-choice --transports implicit-godunov
"""

import argparse
import sys
from pathlib import Path

import numpy as np
import peer  # this script's folder is on sys.path: the scenes of the peer benchmark

from femcrowd import Simulation, load_case
from femcrowd.case.template import door_groups
from femcrowd.mesh import load_domain
from femcrowd.studies.evacuation import LAST, evacuation_times
from femcrowd.studies.recommended import FREE_SPEED, MACRO, door_capacity
from femcrowd.studies.validation import flow
from femcrowd.timer import Stopwatch

#: the reference: the explicit LWR fluxes at their whole CFL step
REFERENCE = ("explicit LWR, cfl 1", {"time.cfl": 1.0})
#: the implicit step rules compared with it, per transport: its median cell's cfl numbers
CFLS = {"implicit": (1, 2), "implicit-godunov": (1, 2, 4)}


def series(transport: str, cfls=None) -> list:
    """(label, overrides) of each step of `transport` on the median cell (its CFLS, or `cfls`)."""
    return [(f"{transport}, median cell, cfl {c:g}", {"scheme.transport": transport, "time.cfl_quantile": 0.5,
                                                      "time.cfl": float(c)}) for c in cfls or CFLS[transport]]


def small_step(transport: str) -> tuple:
    """``--small-step``: the implicit prediction at a tenth of the smallest cell's step (its flux, not its step)."""
    return f"{transport}, smallest cell, cfl 0.1", {"scheme.transport": transport, "time.cfl": 0.1}


#: per scene: its case directory (a function: the peer scenes are made on demand) and its own overrides
SCENES = {
    "bottleneck": (lambda: peer.scene("bottleneck", 90)[0], {"velocity.speed": FREE_SPEED}),
    "hall": (lambda: peer.scene("hall", 100)[0], {}),
    "hall-1000": (lambda: peer.scene("hall", 1000)[0], {}),
    "route-queues": (lambda: Path("cases/route-queues"), {}),
    "route-choice": (lambda: Path("cases/route-choice"), {}),
    "rimea-12": (lambda: Path("cases/rimea/test12-bottlenecks"), {}),
}
SHARES = ("t50", "t90", "t99", "t_last")


def recommended(directory: Path, level: int) -> dict:
    """The recommended settings of a case: MACRO without push, "auto" on every exit and interior door."""
    case = load_case(directory)
    domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"])
    exits, _, inside = door_groups(domain)
    doors = [*case["boundary"]["exits"], *inside]
    return {**MACRO, "velocity.push": 0.0, **door_capacity(doors), "mesh.refine": level}


def run(directory: Path, overrides: dict) -> dict:
    """One run until the crowd has left: cells, steps, CPU seconds, the four times and each door's flow."""
    case = load_case(directory, overrides)
    clock = Stopwatch()
    simulation = Simulation(case)
    result = simulation.run()
    h = result.history
    total = h["mass"][0]
    times = evacuation_times(h["time"], h["evacuated"], total, (0.5, 0.9, 0.99, 1 - LAST / total))
    doors = {}
    for name in case["boundary"]["capacity"]:
        passed = np.cumsum(h[f"flow_{name}"][1:] * np.diff(h["time"]))
        doors[name] = flow(h["time"][1:], passed, passed[-1]) if passed[-1] > 1 else float("nan")
    return {"cells": simulation.scene.domain.ncells, "steps": len(h["time"]) - 1, "cpu": clock.cpu,
            **dict(zip(SHARES, times)), **{f"flow {d}": f for d, f in doors.items()}}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--levels", type=int, default=1, help="meshes: mesh.refine 0..levels-1")
    parser.add_argument("--transports", nargs="+", default=list(CFLS), choices=list(CFLS))
    parser.add_argument("--cfl", nargs="+", type=float, help="the median cell's cfl numbers (default: CFLS)")
    parser.add_argument("--small-step", action="store_true", help="also the implicit prediction at a tenth of the "
                        "smallest cell's step")
    args = parser.parse_args()
    steps = [row for transport in args.transports for row in series(transport, args.cfl)]
    rules = [REFERENCE, *steps, *[small_step(t) for t in args.transports if args.small_step]]
    within = dict.fromkeys([label for label, _ in steps], True)   # each rule within 1 % on every scene and mesh
    for name in args.scenes:
        make, own = SCENES[name]
        directory = make()
        print(f"\n{name} ({directory})", flush=True)
        for level in range(args.levels):
            settings = {**recommended(directory, level), **own}
            rows = [(label, run(directory, {**settings, **step})) for label, step in rules]
            reference = rows[0][1]
            keys = [k for k in reference if k in SHARES or k.startswith("flow ")]
            print("| series | cells | steps | CPU (s) | " + " | ".join(keys) + " |")
            print("|---|---:|---:|---:|" + "---:|" * len(keys))
            for label, r in rows:
                if r is reference:
                    cells = [f"{r[k]:.4g}" for k in keys]
                else:
                    errors = [100 * (r[k] - reference[k]) / reference[k] for k in keys]
                    cells = [f"{e:+.2f} %" for e in errors]
                    if label in within:
                        within[label] &= all(abs(e) <= 1 for e in errors)
                print(f"| {label} | {r['cells']} | {r['steps']} | {r['cpu']:.3g} | " + " | ".join(cells) + " |",
                      flush=True)
    print()
    for label, yes in within.items():
        print(f"{label} within 1 % of explicit cfl 1 on every scene and mesh: {'yes' if yes else 'no'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
