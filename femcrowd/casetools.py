"""New cases and case reports: ``femcrowd new`` and ``femcrowd info``.

``new_case`` writes a commented case.toml for a mesh (defaults from the case
SCHEMA, exits = the mesh's boundary groups not named wall*). ``case_info``
resolves a case, measures its mesh (Domain.statistics) and estimates the run:
number of steps end / (cfl * CFL-1 step) and run time from a few timed steps
of the real solver (see ``estimate``).
"""

import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from .case import SCHEMA
from .errors import InputError
from .mesh import load_domain

#: timed transport steps of ``femcrowd info``
TIMED_CALLS = 20


def toml_value(value):
    """A value as TOML text (strings and lists via JSON, which is valid TOML for them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    return json.dumps(value)


def _default(section, key):
    return toml_value(SCHEMA[section][key].default)


def wall_like(name):
    return name.lower().startswith("wall")


def new_case(case_dir, mesh_file):
    """Write CASE_DIR/case.toml for the mesh ``mesh_file``; never overwrites. Returns the file."""
    case_dir, mesh_file = Path(case_dir), Path(mesh_file)
    file = case_dir / "case.toml"
    if file.exists():
        raise InputError(file, None, None, "already exists: femcrowd new never overwrites a case "
                         "(choose another directory, or edit this file)")
    domain = load_domain(mesh_file, (), 0, case_file=file)
    groups = domain.statistics()["boundary_groups"]
    exits = [name for name in groups if not wall_like(name)]
    surfaces = [name for name in (domain.mesh.subdomains or {}) if not name.startswith("gmsh:")]
    (x0, y0), (x1, y1) = domain.points.min(axis=0), domain.points.max(axis=0)
    # about four walks across the floor at 1 m/s; the run stops earlier once everybody has left
    end = 10.0 * math.ceil(0.4 * math.hypot(x1 - x0, y1 - y0))
    relative = Path(os.path.relpath(mesh_file.resolve(), case_dir.resolve())).as_posix()
    group_list = ", ".join(f"{n} ({groups[n]:.3g} m)" for n in groups) or "none"
    if exits:
        velocity = [('type = "exits"', "U = -speed grad d / |grad d|, d = walking distance to the nearest exit"),
                    (f'speed = {_default("velocity", "speed")}', "m/s: number or expression in x, y"),
                    ('# type = "field"', "or U given by expressions in x, y, t:"), '# ux = "-1"', '# uy = "0"']
    else:
        velocity = [('type = "field"', "the mesh has no exit: U given by expressions in x, y, t"),
                    'ux = "1"', 'uy = "0"']
    lines = [
        f"# femcrowd case written by `femcrowd new` for {mesh_file.name}.",
        "# Keys left out take their default (see the case-format documentation). Run it with",
        f"#   femcrowd run {case_dir}",
        f"title = {toml_value(case_dir.resolve().name)}",
        "", "[mesh]",
        (f"file = {toml_value(relative)}", "gmsh .msh (2.2 or 4.1), relative to this file"),
        (f'refine = {_default("mesh", "refine")}', "uniform refinements after loading (convergence studies)"),
        "", "[boundary]",
        f"# boundary groups of the mesh: {group_list}",
        (f"exits = {toml_value(exits)}", "groups that are exits; every other boundary edge is a wall"),
        "", "[model]",
        (f'type = {_default("model", "type")}', '"macro" (density) | "micro" (discs)'),
        (f'rho_max = {_default("model", "rho_max")}', "saturation density in your unit, e.g. 5.0 (people/m^2)"),
        "", ("[velocity]", "desired velocity U"), *velocity,
        "", "[initial]",
        ("density = 0.5", 'unit of rho_max: number or expression in x, y, e.g. "0.8 * (x < 4)"'),
        ("# [initial.regions]", f"or per surface group ({', '.join(surfaces) or 'none'}): crowd = 0.9"),
        "", "[time]",
        (f"end = {end:g}.0", f"s (the floor is {x1 - x0:.3g} m x {y1 - y0:.3g} m)"),
        (f'cfl = {_default("time", "cfl")}', "time step from the CFL number of the desired velocity"),
        ("# dt = 0.01", "or a fixed time step (s)"),
        (f'stop_when_empty = {_default("time", "stop_when_empty")}', "stop once everybody has left"),
        "", "[output]",
        (f'dir = {_default("output", "dir")}', "relative to this file"),
        (f'every = {_default("output", "every")}', "s between frames"),
        f'fields = {_default("output", "fields")}',
        "", ("# [micro]", 'model.type = "micro" only'),
        (f'# radius = {_default("micro", "radius")}', "m, or [min, max] for a polydisperse crowd"),
        f'# seed = {_default("micro", "seed")}',
    ]
    text = "".join((f"{line[0]:<30}  # {line[1]}" if isinstance(line, tuple) else line) + "\n" for line in lines)
    case_dir.mkdir(parents=True, exist_ok=True)
    file.write_text(text)
    return file


def estimate(scene):
    """Steps and run time of a macro scene (sets its projection's warm start: use a fresh scene).

    Steps: end / dt with dt = cfl * (CFL-1 step of the upwind scheme) or the
    fixed dt (fewer when the room empties first). Time per step is measured
    on the scene's solver: a 'free' step is the transport step (no cell over
    saturation, nothing to project); a 'congested' step adds the projection
    of the initial crowd's cells pushed 5 % over saturation, warm-started as
    in a run. The run time lies between all-free and all-congested, plus the
    frames (one frame timed).
    """
    from .output import FrameSeries, triangle_frame
    from .run import frame_fields

    case, solver = scene.case, scene.solver
    end = case["time"]["end"]
    dt = solver.stable_dt()
    steps = math.ceil(end / dt) if math.isfinite(dt) else 1
    crowd = solver.rho > 0
    congested_input = np.where(crowd, 1.05, 0.0)
    frames = math.floor(end / case["output"]["every"] + 1e-9) + 1
    with tempfile.TemporaryDirectory() as tmp:
        tic = time.perf_counter()
        FrameSeries(tmp, "solution").write(0.0, triangle_frame(scene.domain, frame_fields(scene)))
        frame_seconds = time.perf_counter() - tic
    free = _median_seconds(lambda: solver.transport.step(solver.rho, dt), TIMED_CALLS)
    projection = 0.0
    if crowd.any():
        solver.projection(congested_input)  # cold start: builds the active set
        projection = _median_seconds(lambda: solver.projection(congested_input), 3)
    return {"dt": dt, "steps": steps, "frames": frames, "free_step_seconds": free,
            "congested_step_seconds": free + projection, "congested_cells": int(crowd.sum()),
            "frame_seconds": frame_seconds,
            "seconds": (steps * free + frames * frame_seconds,
                        steps * (free + projection) + frames * frame_seconds)}


def _median_seconds(call, repeat):
    """Median wall time of a call (robust to a busy machine)."""
    durations = []
    for _ in range(repeat):
        tic = time.perf_counter()
        call()
        durations.append(time.perf_counter() - tic)
    return float(np.median(durations))


def case_info(case):
    """Resolved configuration, mesh statistics and (macro) run estimate of a loaded case."""
    from .run import setup_macro

    info = {"case_file": str(case.file), "config": case.config}
    if case["model"]["type"] == "macro":
        scene = setup_macro(case)
        info["mesh"] = scene.domain.statistics()
        info["exits"] = list(scene.domain.exit_group)
        info["estimate"] = estimate(scene)
    else:
        domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"],
                             case["mesh"]["refine"], case.file)
        info["mesh"], info["exits"] = domain.statistics(), list(domain.exit_group)
    return info


def _duration(seconds):
    return f"{seconds:.2g} s" if seconds < 60 else f"{seconds / 60:.2g} min"


def format_info(info):
    """The report printed by ``femcrowd info``."""
    lines = [f"case: {info['case_file']}", "", "resolved configuration (defaults filled in):"]
    for section, values in info["config"].items():
        if not isinstance(values, dict):
            lines.append(f"  {section} = {toml_value(values)}")
            continue
        lines.append(f"  [{section}]")
        lines += [f"    {k} = {'(not set)' if v is None else toml_value(v)}" for k, v in values.items()]
    m = info["mesh"]
    lines += ["", "mesh:",
              f"  {m['triangles']} triangles, {m['nodes']} nodes, area {m['area']:.4g} m^2",
              f"  edge length h: min {m['h_min']:.3g} m, max {m['h_max']:.3g} m",
              f"  angles: min {m['min_angle_deg']:.1f} deg, max {m['max_angle_deg']:.1f} deg; "
              f"smallest cell {m['min_cell_area']:.3g} m^2",
              "  Delaunay: " + ("yes (all interior pairs)" if m["non_delaunay_pairs"] == 0 else
                                f"NO: {m['non_delaunay_pairs']} non-Delaunay pairs") +
              f"; {m['clipped_transmissibilities']} transmissibilities clipped to keep the M-matrix",
              "  boundary groups:"]
    for name, length in m["boundary_groups"].items():
        lines.append(f"    {name:<16} {length:9.4g} m   {'exit' if name in info['exits'] else 'wall'}")
    e = info.get("estimate")
    if e is None:
        lines += ["", "run estimate: macro cases only"]
        return "\n".join(lines)
    low, high = e["seconds"]
    lines += ["", "run estimate:",
              f"  time step {e['dt']:.4g} s -> about {e['steps']} steps"
              " (fewer if everybody has left before the end)",
              f"  {e['frames']} frames",
              f"  run time: {_duration(low)} (no congestion) to {_duration(high)} "
              f"(the initial crowd's {e['congested_cells']} cells congested at every step)",
              f"  measured here: {1e3 * e['free_step_seconds']:.3g} ms per free step, "
              f"{1e3 * e['congested_step_seconds']:.3g} ms per congested step, "
              f"{1e3 * e['frame_seconds']:.3g} ms per frame"]
    return "\n".join(lines)
