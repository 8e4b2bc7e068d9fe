"""femcrowd beside JuPedSim, the agent-based peer, on the same scenes: wall time, evacuation time and flow.

Scenes (each a TOML floor plan, benchmarks/.cache/peer; JuPedSim reads the same outline and exits):
- bottleneck: the 1 m bottleneck of docs/validation.md (femcrowd/studies/validation.py: a waiting area of
  8 m x 6 m, a corridor 2 m long, 90 people at 2.5 /m^2 on its first 6 m);
- hall: a 40 m x 30 m hall with two 2 m exits, in the middle of its short walls, and `--people` people spread
  evenly over its middle 30 m x 20 m;
- large-hall: the hall scaled by sqrt(10) (126.5 m x 94.9 m, the same 2 m exits and cells), `--people` people
  over its middle three quarters by two thirds: 10 000 are the density of 1 000 in the hall (about 227 000
  triangles, some 1 300 s to empty through the two exits at 1.9 /(m s)). `--only femcrowd` runs one program
  (JuPedSim needs more than 10 minutes for 10 000 agents).
`--coarsen K` meshes the halls with cells K times the benchmark's (0.35 m inside, 0.1 m along the exits): K = 2
has a quarter of its triangles, K = 0.5 four times as many (the evacuation time's dependence on the mesh).

femcrowd runs the macro model with the recommended settings of femcrowd/studies/recommended.py (MACRO:
Predtechenskii and Milinskii's law, slip walls, STEP; their free speed FREE_SPEED, 1.67 m/s; door_capacity: the
capacity of its width on every exit; `--implicit CFL`: the linearly implicit prediction at CFL times the median
cell's step instead of STEP; `--fast`: the named fast step FAST_STEP, implicit-godunov at 1.5 times the median
cell's step, instead of STEP), as `femcrowd run` does (history.csv, a frame every 10 s); JuPedSim
its default collision-free speed model (Tordeux et al. 2016) at dt = 0.01 s, agents of radius 0.2 m with
the same desired speed FREE_SPEED, placed at random (`--seed`) in the crowd's area, each heading for the exit
nearest to it and taken out when it reaches a strip 0.5 m deep inside that exit. Wall time: the set-up and the
run (not the imports, nor the meshing, done once), with the process's CPU time beside it (less sensitive to the
other jobs of a shared machine); evacuation time: femcrowd's (less than 10^-4 of the crowd inside) with, in
brackets, its last person's (all but half a person out, as `femcrowd evacuation-times` reads it:
femcrowd/studies/evacuation.py, LAST), and JuPedSim's last agent out; flow: the slope of the people out against
time from 20 % to 80 % of them out (femcrowd/studies/validation.py, flow), persons per second through all exits.
Each run is a fresh process, femcrowd and JuPedSim alternated over `--repeat` rounds; the table gives the medians.

JuPedSim is an optional benchmark dependency: pip install -e '.[peer]' (or pip install jupedsim).

    python benchmarks/peer.py                                   # bottleneck, hall with 100 people
    python benchmarks/peer.py --scenes hall --people 100 1000 --repeat 3
    python benchmarks/peer.py --scenes large-hall --people 10000 --only femcrowd --implicit 4
    python benchmarks/peer.py --scenes hall --only femcrowd --implicit 1 --coarsen 2
    python benchmarks/peer.py --scenes hall --people 100 1000 --coarsen 2 --fast --repeat 3
"""

import argparse
import importlib.util
import json
import os
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from alternating import in_process, median, rounds  # this script's folder is on sys.path

CACHE = Path(__file__).resolve().parent / ".cache" / "peer"
RADIUS, DT = 0.2, 0.01
#: simulated seconds after which a run that has not emptied stops
MAX_TIME = 1000.0
HALL_PLAN = """size = {size:.6g}
[outer]
points = [[0, 0], [{w:.6g}, 0], [{w:.6g}, {h:.6g}], [0, {h:.6g}]]
[[exits]]
name = "west"
from = [0, {y0:.6g}]
to = [0, {y1:.6g}]
size = {exit_size:.6g}
[[exits]]
name = "east"
from = [{w:.6g}, {y0:.6g}]
to = [{w:.6g}, {y1:.6g}]
size = {exit_size:.6g}
"""
HALL_CROWD = (5.0, 35.0, 5.0, 25.0)   # x0, x1, y0, y1 of the crowd in the hall
#: the hall's scale factor per scene: the large hall has 10 times its area
HALLS = {"hall": 1.0, "large-hall": 10 ** 0.5}
HALL_CASE = """title = "A {w:.4g} m x {h:.4g} m hall, two 2 m exits, {people} people (benchmarks/peer.py)"
[mesh]
file = "../{name}.msh"
[boundary]
exits = ["west", "east"]
[model]
rho_max = 5.4
[initial]
density = "{density!r} * (x > {x0}) * (x < {x1}) * (y > {y0}) * (y < {y1})"
[time]
end = {end}
[output]
every = 10.0
"""


def scene(name: str, people: int, coarsen: float = 1.0) -> tuple:
    """(case directory, plan file, crowd box, people) of a scene, made once under CACHE; the halls' cells `coarsen`
    times the benchmark's."""
    from femcrowd.mesh.floorplan import build_mesh
    from femcrowd.studies.validation import scene as bottleneck

    if name == "bottleneck":
        directory = bottleneck(1.0, CACHE)
        return directory, directory / "bottleneck.toml", (0.0, 6.0, 0.0, 6.0), 90
    k = HALLS[name]
    w, h = 40.0 * k, 30.0 * k
    mesh = name if coarsen == 1 else f"{name}-coarsen{coarsen:g}"
    plan, directory = CACHE / f"{mesh}.toml", CACHE / f"{mesh}-{people}"
    if not plan.with_suffix(".msh").exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        plan.write_text(HALL_PLAN.format(w=w, h=h, y0=h / 2 - 1, y1=h / 2 + 1, size=0.35 * coarsen,
                                         exit_size=0.1 * coarsen))
        build_mesh(plan)
    x0, x1, y0, y1 = box = tuple(k * c for c in HALL_CROWD)
    if not (directory / "case.toml").exists():
        directory.mkdir()
        (directory / "case.toml").write_text(HALL_CASE.format(
            name=mesh, w=w, h=h, people=people, density=people / ((x1 - x0) * (y1 - y0)), x0=x0,
            x1=x1, y0=y0, y1=y1, end=MAX_TIME * k))
    return directory, plan, box, people


def run_femcrowd(directory: Path, implicit: float = 0.0, fast: bool = False) -> dict:
    """The macro model with the recommended settings, as `femcrowd run` runs it; implicit > 0: the linearly implicit
    prediction at that cfl on the median cell's step instead of the recommended STEP; fast: FAST_STEP instead."""
    import tempfile

    import femcrowd
    from femcrowd.studies.evacuation import LAST, evacuation_times
    from femcrowd.studies.recommended import FAST, FREE_SPEED, MACRO, door_capacity
    from femcrowd.studies.validation import flow

    tic, cpu = time.perf_counter(), time.process_time()
    exits = femcrowd.load_case(directory)["boundary"]["exits"]
    step = {} if not implicit else {"scheme.transport": "implicit", "time.cfl_quantile": 0.5, "time.cfl": implicit}
    settings = FAST if fast else MACRO
    case = femcrowd.load_case(directory, {**settings, "velocity.speed": FREE_SPEED, **step, **door_capacity(exits)})
    with tempfile.TemporaryDirectory() as tmp:
        result = femcrowd.run(case, out=Path(tmp) / "out")
    wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
    h = result.history
    people = float(h["mass"][0])
    return {"wall": wall, "cpu": cpu, "evacuation": result.summary["evacuation_time"] or np.nan,
            "last": evacuation_times(h["time"], h["evacuated"], people, [1 - LAST / people])[0],
            "flow": flow(h["time"], h["evacuated"], people), "people": people, "steps": result.summary["steps"],
            "cells": result.domain.ncells}


def run_jupedsim(plan_file: Path, box, people: int, seed: int) -> dict:
    """JuPedSim's collision-free speed model on the plan's outline, the agents taken out at its exits."""
    import jupedsim as jps
    import shapely

    from femcrowd.studies.recommended import FREE_SPEED
    from femcrowd.studies.validation import flow

    plan = tomllib.loads(Path(plan_file).read_text())
    area = shapely.Polygon(plan["outer"]["points"])
    tic, cpu = time.perf_counter(), time.process_time()
    simulation = jps.Simulation(model=jps.CollisionFreeSpeedModel(), geometry=area, dt=DT)
    exits = [simulation.add_exit_stage(_strip(area, exit["from"], exit["to"])) for exit in plan["exits"]]
    journeys = [simulation.add_journey(jps.JourneyDescription([stage])) for stage in exits]
    doors = [shapely.LineString([exit["from"], exit["to"]]) for exit in plan["exits"]]
    x0, x1, y0, y1 = box
    positions = jps.distribute_by_number(polygon=shapely.box(x0, y0, x1, y1), number_of_agents=people,
                                         distance_to_agents=2 * RADIUS, distance_to_polygon=RADIUS, seed=seed)
    for position in positions:   # each agent to the exit nearest to it
        k = int(np.argmin([shapely.Point(position).distance(door) for door in doors]))
        simulation.add_agent(jps.CollisionFreeSpeedModelAgentParameters(
            position=position, journey_id=journeys[k], stage_id=exits[k], desired_speed=FREE_SPEED, radius=RADIUS))
    times, out = [0.0], [0]
    while simulation.agent_count() > 0 and simulation.elapsed_time() < MAX_TIME:
        simulation.iterate()
        left = people - simulation.agent_count()
        if left > out[-1]:
            times.append(simulation.elapsed_time())
            out.append(left)
    wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
    times, out = np.array(times), np.array(out, float)
    return {"wall": wall, "cpu": cpu, "evacuation": times[-1] if out[-1] == people else np.nan,
            "flow": flow(times, out, people), "people": people, "steps": simulation.iteration_count()}


def _strip(area, a, b, depth: float = 0.5):
    """The strip `depth` deep inside the area along the exit segment a-b (JuPedSim's exit stage)."""
    import shapely

    a, b = np.asarray(a, float), np.asarray(b, float)
    normal = np.array([b[1] - a[1], a[0] - b[0]]) / np.linalg.norm(b - a)
    if not area.contains(shapely.Point((a + b) / 2 + 0.01 * normal)):
        normal = -normal
    return shapely.Polygon([a, b, b + depth * normal, a + depth * normal])


def worker(tool: str, name: str, people: int, seed: int, implicit: float, coarsen: float, fast: bool) -> None:
    directory, plan, box, people = scene(name, people, coarsen)
    figures = run_femcrowd(directory, implicit, fast) if tool == "femcrowd" else run_jupedsim(plan, box, people, seed)
    print(json.dumps({k: float(v) for k, v in figures.items()}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["bottleneck", "hall"], choices=["bottleneck", *HALLS])
    parser.add_argument("--people", nargs="+", type=int, default=[100], help="people in the hall")
    parser.add_argument("--only", choices=["femcrowd", "jupedsim"], help="run one of the two programs")
    parser.add_argument("--repeat", type=int, default=1, help="rounds of the two programs")
    parser.add_argument("--seed", type=int, default=1, help="JuPedSim's placement of the agents")
    step = parser.add_mutually_exclusive_group()
    step.add_argument("--implicit", type=float, default=0.0, metavar="CFL",
                      help="femcrowd with the implicit prediction at CFL x the median cell's step, not STEP")
    step.add_argument("--fast", action="store_true",
                      help="femcrowd with the fast step FAST_STEP (implicit-godunov, cfl 1.5 on the median cell)")
    parser.add_argument("--coarsen", type=float, default=1.0, metavar="K",
                        help="the halls' cells K times the benchmark's (0.35 m, 0.1 m at the exits)")
    parser.add_argument("--worker", nargs=7, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        tool, name, people, seed, implicit, coarsen, fast = args.worker
        return worker(tool, name, int(people), int(seed), float(implicit), float(coarsen), fast == "1")
    tools = [("femcrowd", None, "femcrowd"), ("JuPedSim", None, "jupedsim")]
    tools = [t for t in tools if args.only in (None, t[2])]
    if args.only != "femcrowd" and importlib.util.find_spec("jupedsim") is None:
        print("benchmarks/peer.py needs JuPedSim: pip install -e '.[peer]' (or pip install jupedsim)", file=sys.stderr)
        return 2
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    runs = [(name, people) for name in args.scenes for people in (args.people if name in HALLS else [90])]
    step = (f"the implicit prediction at cfl {args.implicit:g} on the median cell" if args.implicit
            else "FAST_STEP" if args.fast else "STEP")
    print(f"medians of {args.repeat} alternated rounds; femcrowd: macro, recommended settings ({step}); JuPedSim "
          f"{_version() if args.only != 'femcrowd' else '(not run)'}: collision-free speed model, dt {DT} s, "
          f"seed {args.seed}")
    print("| scene | people | femcrowd wall (CPU) | JuPedSim wall (CPU) | femcrowd evacuation (last person) | "
          "JuPedSim evacuation "
          "| femcrowd flow | JuPedSim flow | femcrowd steps (triangles) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, people in runs:
        scene(name, people, args.coarsen)   # meshed once, before anything is timed
        worker_args = (name, people, args.seed, args.implicit, args.coarsen, int(args.fast))
        result = rounds(tools, args.repeat, lambda code, tool: in_process(__file__, (tool, *worker_args), code, env))
        missing = [{"wall": np.nan, "cpu": np.nan, "evacuation": np.nan, "last": np.nan, "flow": np.nan,
                    "steps": np.nan, "cells": np.nan}]
        f, j = result.get("femcrowd", missing), result.get("JuPedSim", missing)
        print(f"| {name} | {people} | {median(f, 'wall'):.1f} s ({median(f, 'cpu'):.2f}) | "
              f"{median(j, 'wall'):.1f} s ({median(j, 'cpu'):.2f}) | "
              f"{median(f, 'evacuation'):.1f} s ({median(f, 'last'):.1f} s) | {median(j, 'evacuation'):.1f} s | "
              f"{median(f, 'flow'):.2f} /s | "
              f"{median(j, 'flow'):.2f} /s | {median(f, 'steps'):.0f} ({f[0]['cells']:.0f}) |", flush=True)
    print(f"load average {os.getloadavg()[1]:.1f} (5 min) at the end")
    return 0


def _version() -> str:
    from importlib.metadata import version

    return version("jupedsim")


if __name__ == "__main__":
    sys.exit(main())
