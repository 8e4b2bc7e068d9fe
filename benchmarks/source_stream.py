"""A source's steady stream at each kind of step (issue 38; docs/scenes.md, "Sources at a large step").

The scene: a corridor 12 m long and 2 m wide, people arriving at q persons/(m s) (`--flow`, default 1.0) through
its west side and walking at v = 1.3 m/s (the paper's model, f = 1) to the east side, all exit. A free stream of
flow q at speed v has the density q / v. Per step (the explicit upwind step at cfl 0.5, the schema's; the fast step
FAST_STEP of femcrowd/studies/recommended.py; implicit-godunov and implicit at 3 times the median cell's CFL step)
it prints the steps of the 20 s run, the mean density over 3 < x < 9 at t = 20 s against q / v, what entered
against what arrived (q x 2 m x 20 s) and what waits outside.

    python benchmarks/source_stream.py
    python benchmarks/source_stream.py --flow 0.5 --size 0.5
"""

import argparse

import numpy as np

import femcrowd.api as fc
from femcrowd.driver.run import Simulation
from femcrowd.studies.recommended import FAST_STEP

SPEED, WIDTH, END = 1.3, 2.0, 20.0
STEPS = {"upwind, cfl 0.5": {}, "fast step": FAST_STEP,
         "implicit-godunov, cfl 3": {"scheme.transport": "implicit-godunov", "time.cfl_quantile": 0.5, "time.cfl": 3.0},
         "implicit, cfl 3": {"scheme.transport": "implicit", "time.cfl_quantile": 0.5, "time.cfl": 3.0}}


def stream(flow, size):
    """Per step: (steps, mean density downstream / (q / v), inflow, queued)."""
    plan = {"size": size, "outer": {"points": [[0, 0], [12, 0], [12, WIDTH], [0, WIDTH]]},
            "exits": [{"name": "entrance", "from": [0, WIDTH], "to": [0, 0]},
                      {"name": "exit", "from": [12, 0], "to": [12, WIDTH]}]}
    scene = fc.Scene(plan)
    rows = {}
    for name, step in STEPS.items():
        settings = {"boundary": {"exits": ["exit"]}, "velocity": {"speed": SPEED}, "time": {"end": END},
                    "output": {"every": END}, "sources": [{"boundary": "entrance", "flow": flow}]}
        for key, value in step.items():
            table, key = key.split(".")
            settings.setdefault(table, {})[key] = value
        simulation = Simulation(scene.case(**settings))
        history = simulation.run(stop_when_empty=False).history
        domain, rho = simulation.model.solver.domain, simulation.model.state.density
        x = domain.centroid[:, 0]
        down = (x > 3.0) & (x < 9.0)
        held = np.sum(domain.area[down] * rho[down]) / np.sum(domain.area[down])
        rows[name] = (len(history["time"]) - 1, held / (flow / SPEED), history["inflow"][-1], history["queued"][-1])
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flow", type=float, default=1.0, help="q, persons/(m s)")
    parser.add_argument("--size", type=float, default=0.25, help="the mesh size, m")
    args = parser.parse_args()
    print(f"q = {args.flow} /(m s), v = {SPEED} m/s, q / v = {args.flow / SPEED:.4f}, mesh size {args.size} m; "
          f"arrived by t = {END:g} s: {args.flow * WIDTH * END:g}")
    print("step | steps | density / (q / v) - 1 | inflow | queued")
    for name, (steps, held, inflow, queued) in stream(args.flow, args.size).items():
        print(f"{name} | {steps} | {held - 1:+.4f} | {inflow:.4f} | {queued:.4f}")


if __name__ == "__main__":
    main()
