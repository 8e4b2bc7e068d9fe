"""Mesh load, distance field and transport step of the macro solver on the hall of benchmarks/scale.py.

Per size, in its own process, medians over --repeat runs (load, distance) or --steps steps:

- mesh load: femcrowd.mesh.load_domain(path, ["exit"]) of the cached gmsh mesh;
- distance field: ExitsVelocity(domain, Expression("1")).cells(exits) (distance to the door + U per cell);
- the same on the hall meshed by gmsh's Delaunay algorithm without smoothing (Mesh.Algorithm 5,
  Mesh.Smoothing 0; cached as hall_delaunay_N.msh), the mesh of the first scale.py runs, where
  obtuse triangles made the relaxations of the distance field pile up;
- transport step: UpwindTransport.step at CFL 0.5 (the solver's default), transport alone, from
  the second step on (the first one builds the update matrix B);
- one CSR mat-vec B @ rho with the same matrix (the floor of a transport step).

    python benchmarks/setup_phases.py                      # 1e5 and 1e6 triangles
    python benchmarks/setup_phases.py --sizes 1e5 --repeat 5

OPENBLAS_NUM_THREADS=1 as in scale.py.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import scale  # noqa: E402  (the hall, its density and its mesh cache)


def delaunay_mesh_file(target):
    """The hall meshed by gmsh's Delaunay algorithm, no smoothing (made on first use)."""
    from femcrowd.mesh.floorplan import build_mesh

    path = scale.CACHE / f"hall_delaunay_{int(target)}.msh"
    if not path.exists():
        plan = path.with_suffix(".toml")
        scale.CACHE.mkdir(exist_ok=True)
        plan.write_text(scale.HALL.format(size=math.sqrt(2.31 * scale.AREA / target)))
        build_mesh(plan, path, gmsh_options={"Mesh.Algorithm": 5, "Mesh.Smoothing": 0})
    return path


def median_time(f, repeat):
    """Median wall time of f() over repeat calls, and the last result."""
    times = []
    for _ in range(repeat):
        tic = time.perf_counter()
        result = f()
        times.append(time.perf_counter() - tic)
    return float(np.median(times)), result


def elapsed(f):
    tic = time.perf_counter()
    f()
    return time.perf_counter() - tic


def one_size(target, repeat, steps):
    from femcrowd.case import Expression
    from femcrowd.macro import MacroState
    from femcrowd.macro.transport import UpwindTransport
    from femcrowd.macro.velocity import ExitsVelocity
    from femcrowd.mesh import Boundary, load_domain

    def distance_field(domain):
        velocity = ExitsVelocity(domain, Expression("1"))
        velocity.cells(Boundary(domain).at(0.0))
        return velocity

    out = {"target": target}
    out["mesh_load"], domain = median_time(lambda: load_domain(scale.mesh_file(target), ["exit"]), repeat)
    out["triangles"] = domain.ncells
    out["distance"], velocity = median_time(lambda: distance_field(domain), repeat)
    delaunay = load_domain(delaunay_mesh_file(target), ["exit"])
    out["delaunay_triangles"] = delaunay.ncells
    out["distance_delaunay"], _ = median_time(lambda: distance_field(delaunay), repeat)
    delaunay = None  # its memory, before the transport steps

    exits = Boundary(domain).at(0.0)
    state = MacroState.initial(np.zeros((1, domain.ncells)), 1)
    transport = UpwindTransport(domain, exits, velocity.normal_on_facets(state, exits))
    dt = 0.5 * transport.max_dt
    rho = Expression(scale.DENSITY)(*domain.centroid.T, 0.0)
    mass0 = domain.area @ rho
    rho, evacuated, _ = transport.step(rho, dt)  # the first step applies F: B is built on the second
    rho, out_step, _ = transport.step(rho, dt)
    evacuated = float(evacuated.sum() + out_step.sum())
    update = transport._update
    times = {"transport": [], "matvec": []}
    for _ in range(steps):  # interleaved, so that both see the same load of the machine
        tic = time.perf_counter()
        rho, out_step, _ = transport.step(rho, dt)
        times["transport"].append(time.perf_counter() - tic)
        evacuated += float(out_step.sum())
        times["matvec"].append(elapsed(lambda: update @ rho))
    out.update({key: float(np.median(value)) for key, value in times.items()})
    out["mass_error"] = abs(domain.area @ rho + evacuated - mass0) / mass0
    out["min_density"] = float(rho.min())
    out["nnz"] = update.nnz
    return out


ROWS = [("triangles (hall / Delaunay hall)", None, None), ("mesh load [s]", "mesh_load", "{:.2f}"),
        ("distance field [s]", "distance", "{:.2f}"),
        ("distance field, Delaunay mesh without smoothing [s]", "distance_delaunay", "{:.2f}"),
        ("transport step [ms]", "transport", "ms"), ("one CSR mat-vec B @ rho [ms]", "matvec", "ms"),
        ("non-zeros of B", "nnz", "{:.0f}"), ("mass error after the steps (relative)", "mass_error", "{:.1e}"),
        ("min density", "min_density", "{:.1e}")]


def table(results):
    return scale.table(results, ROWS, lambda r: f"{r['triangles']} / {r['delaunay_triangles']}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e5, 1e6], help="target triangle counts")
    parser.add_argument("--repeat", type=int, default=3, help="runs of the load and distance phases")
    parser.add_argument("--steps", type=int, default=30, help="transport steps and mat-vecs")
    parser.add_argument("--one", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_size(args.one, args.repeat, args.steps)))
        return
    results = []
    env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
    for size in args.sizes:
        scale.mesh_file(size), delaunay_mesh_file(size)  # meshing is not timed
        done = subprocess.run([sys.executable, __file__, "--one", str(size), "--repeat", str(args.repeat),
                               "--steps", str(args.steps)], check=True, capture_output=True, text=True, env=env)
        results.append(json.loads(done.stdout.strip().splitlines()[-1]))
        print(f"size {size:.0e} done", file=sys.stderr, flush=True)
    print(table(results))


if __name__ == "__main__":
    main()
