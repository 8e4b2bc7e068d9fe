"""Run controller: case -> scene setup -> time loop -> outputs (PyClaw's controller role).

Everything that can fail on bad input (mesh, exits, expressions, initial
density) is checked in :func:`setup_macro` before the output directory is
touched, so a bad case never overwrites results.
"""

import time

import numpy as np
from tqdm import tqdm

from . import __version__
from .errors import InputError
from .expressions import Expression
from .macro import MacroSolver
from .mesh import file_checksum, load_domain
from .output import FrameSeries, History, copy_case, prepare_output_dir, triangle_frame, write_json
from .projection import Projection
from .velocity import ExitsVelocity, FieldVelocity

HISTORY_COLUMNS = ["time", "dt", "mass", "evacuated", "max_density", "saturated_area",
                   "max_pressure", "active_set_iterations", "step_seconds",
                   "min_density", "min_pressure", "complementarity", "linear_residual"]


class Scene:
    """A macro scene ready to run: domain, desired velocity, solver, and setup timings."""

    def __init__(self, case, domain, velocity, solver, timing):
        self.case, self.domain, self.velocity, self.solver, self.timing = \
            case, domain, velocity, solver, timing


def setup_macro(case):
    """Build domain, desired velocity, initial density and solver from a loaded case."""
    timing = {}
    tic = time.perf_counter()
    domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"],
                         case["mesh"]["refine"], case.file)
    timing["mesh"] = time.perf_counter() - tic
    tic = time.perf_counter()
    velocity = desired_velocity(case, domain)
    timing["desired_velocity"] = time.perf_counter() - tic
    rho0 = initial_density(case, domain)
    tic = time.perf_counter()
    projection = Projection(domain, case["projection"]["direct_max"], case["projection"]["tol"])
    solver = MacroSolver(domain, velocity, rho0, case["time"]["cfl"], case["time"]["dt"], projection,
                         case["scheme"]["transport"])
    timing["assembly"] = time.perf_counter() - tic
    check_transport_cfl(case, solver.transport)
    return Scene(case, domain, velocity, solver, timing)


def check_transport_cfl(case, transport):
    """Refuse a time step beyond the transport's own CFL number (max_cfl: 1 for upwind, beyond
    which densities can become negative; 0.5 for the higher-order transports, beyond which
    they oscillate).

    transport: the transport object, or its class when the case has no time.dt."""
    name, limit, dt = case["scheme"]["transport"], transport.max_cfl, case["time"]["dt"]
    if dt is None and case["time"]["cfl"] > limit:
        raise InputError(case.file, "time.cfl", case["time"]["cfl"],
                         f"must be <= {limit:g} with scheme.transport = {name!r}")
    if dt is not None and dt > limit * transport.max_dt:
        raise InputError(case.file, "time.dt", dt, f"exceeds {limit:g} x the CFL limit "
                         f"{transport.max_dt:.3g} s of the upwind scheme, the most scheme.transport = "
                         f"{name!r} allows (use a smaller dt, or time.cfl)")


def desired_velocity(case, domain):
    spec = case["velocity"]
    if spec["type"] == "field":
        where = np.vstack([domain.centroid, domain.midpoint])
        ux, uy = (_checked(case.expression("velocity", k), where, case, "velocity", k) for k in ("ux", "uy"))
        return FieldVelocity(domain, ux, uy)
    if not domain.exit.any():
        raise InputError(case.file, "velocity.type", "exits",
                         "needs at least one exit (set boundary.exits) or use type = 'field'")
    speed = case.expression("velocity", "speed")
    if speed.depends_on_time:
        raise InputError(case.file, "velocity.speed", spec["speed"],
                         "must not depend on t for type = 'exits'")
    return ExitsVelocity(domain, _checked(speed, domain.centroid, case, "velocity", "speed"))


def _checked(expr, xy, case, section, key):
    """Evaluate once to reject non-finite values at load time; return the expression."""
    values = expr(xy[:, 0], xy[:, 1], 0.0)
    if not np.all(np.isfinite(values)):
        raise InputError(case.file, f"{section}.{key}", case[section][key],
                         "gives non-finite values on the mesh")
    return expr


def initial_density(case, domain):
    """Cell averages of the initial density, scaled by rho_max."""
    rho_max = case["model"]["rho_max"]
    density = domain.cell_average(Expression(case["initial"]["density"]))
    if not np.all(np.isfinite(density)):
        raise InputError(case.file, "initial.density", case["initial"]["density"],
                         "gives non-finite values on the mesh")
    subdomains = domain.mesh.subdomains or {}
    for name, value in case["initial"]["regions"].items():
        if name not in subdomains:
            raise InputError(case.file, f"initial.regions.{name}", value,
                             f"no surface group of that name (groups: {', '.join(subdomains) or 'none'})")
        if not 0 <= value <= rho_max:
            raise InputError(case.file, f"initial.regions.{name}", value, f"is outside [0, rho_max = {rho_max:g}]")
        density[np.asarray(subdomains[name])] = value
    low, high = float(density.min()), float(density.max())
    if low < 0 or high > rho_max * (1 + 1e-12):
        bad = low if low < 0 else high
        raise InputError(case.file, "initial.density", case["initial"]["density"],
                         f"density {bad:g} is outside [0, rho_max = {rho_max:g}]")
    return np.minimum(density / rho_max, 1.0)


def frame_fields(scene):
    """The cell fields asked for in [output].fields, in user units."""
    solver, fields = scene.solver, scene.case["output"]["fields"]
    data = {}
    if "density" in fields:
        data["density"] = solver.rho * scene.case["model"]["rho_max"]
    if "pressure" in fields:
        data["pressure"] = solver.p
    if "velocity" in fields:
        data["velocity"] = solver.velocity_field()
    return data


def run_macro(case, out=None, force=False, quiet=False):
    """Run a macro case to its end time; write frames, history and summary. Returns the summary."""
    wall = time.perf_counter()
    scene = setup_macro(case)
    out_dir = prepare_output_dir(case.path(out or case["output"]["dir"]), case.file, force)
    copy_case(case.file, out_dir)
    solver, domain, rho_max = scene.solver, scene.domain, case["model"]["rho_max"]
    frames = FrameSeries(out_dir, "solution")
    history = History(out_dir / "history.csv",
                      HISTORY_COLUMNS + [f"evacuated_{name}" for name in solver.exit_names])
    end, every = case["time"]["end"], case["output"]["every"]
    stop_mass = case["time"]["empty_fraction"] * solver.initial_mass
    can_empty = case["time"]["stop_when_empty"] and domain.exit.any()
    record = Record(solver, rho_max, case["time"]["empty_fraction"] if domain.exit.any() else None)
    summary = {"femcrowd": __version__, "status": "running", "case": case.config,
               "case_file": str(case.file), "output_dir": str(out_dir),
               "mesh": {"file": str(domain.source), "sha256": file_checksum(domain.source),
                        **domain.statistics()}}

    def write_frame():
        tic = time.perf_counter()
        frames.write(solver.t, triangle_frame(domain, frame_fields(scene)))
        solver.timers["output"] += time.perf_counter() - tic

    def finish(status):
        history.close()
        summary.update(status=status, **record.summary(solver))
        summary["timing"] = {**scene.timing, **dict(solver.timers),
                             "wall": time.perf_counter() - wall}
        write_json(out_dir / "summary.json", summary)
        return summary

    def advance(until):
        history.append(record.add(solver, solver.step(until=until)))
        return can_empty and solver.mass <= stop_mass

    return drive(lambda: solver.t, advance, write_frame, finish, end, every, quiet)


def drive(now, advance, write_frame, finish, end, every, quiet):
    """The time loop shared by the macro and micro controllers.

    ``advance(until)`` makes one step that does not pass ``until`` and returns
    True when the domain is empty; steps land exactly on the frame times
    (every ``every`` s) and on ``end``, a frame is written at t = 0, at each
    frame time and at the last step. ``finish(status)`` writes summary.json
    and is called whatever happens: "completed", "interrupted" (Ctrl-C) or
    "failed: ..." (then the exception goes on to the caller).
    """
    write_frame()
    next_frame = every
    bar = tqdm(total=end, disable=quiet, delay=2.0, unit="s", desc="simulated time",
               bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} s [{elapsed}<{remaining}]")
    try:
        while now() < end:
            target = min(next_frame, end)
            before = now()
            emptied = advance(target)
            bar.update(now() - before)
            if now() >= target or emptied:
                write_frame()
                next_frame = next_frame + every if now() >= next_frame else next_frame
            if emptied:
                break
    except KeyboardInterrupt:
        bar.close()
        finish("interrupted")
        raise
    except Exception as err:
        bar.close()
        finish(f"failed: {type(err).__name__}: {err}")
        raise
    bar.close()
    return finish("completed")


class Record:
    """Per-step history rows and the extremes of every invariant over the run."""

    def __init__(self, solver, rho_max, empty_fraction=None):
        self.rho_max, self.empty_fraction = rho_max, empty_fraction
        self.initial_mass = solver.initial_mass
        d = solver.diagnostics()
        self.extremes = {"min_density": d["min_density"], "max_density": d["max_density"],
                         "min_pressure": 0.0, "max_pressure": 0.0, "max_complementarity": 0.0,
                         "max_pressure_unsaturated": 0.0, "max_linear_residual": 0.0,
                         "max_mass_error": 0.0, "max_active_set_iterations": 0, "non_finite": 0}
        self.iterations, self.steps, self.evacuation_time = [], 0, None

    def add(self, solver, info):
        d = solver.diagnostics()
        e = self.extremes
        e["min_density"] = min(e["min_density"], d["min_density"])
        e["max_density"] = max(e["max_density"], d["max_density"])
        e["min_pressure"] = min(e["min_pressure"], d["min_pressure"])
        e["max_pressure"] = max(e["max_pressure"], d["max_pressure"])
        e["max_complementarity"] = max(e["max_complementarity"], d["complementarity"])
        e["max_pressure_unsaturated"] = max(e["max_pressure_unsaturated"], d["pressure_unsaturated"])
        e["max_linear_residual"] = max(e["max_linear_residual"], info["linear_residual"])
        e["max_active_set_iterations"] = max(e["max_active_set_iterations"], info["active_set_iterations"])
        # NaN/inf would be invisible in the min/max above (comparisons with NaN are False): count them
        e["non_finite"] += int(np.count_nonzero(~np.isfinite(solver.rho)) + np.count_nonzero(~np.isfinite(solver.p)))
        error = abs(d["mass"] + d["evacuated"] - self.initial_mass) / max(self.initial_mass, 1e-300)
        e["max_mass_error"] = max(e["max_mass_error"], error)
        if (self.evacuation_time is None and self.empty_fraction is not None
                and d["mass"] <= self.empty_fraction * self.initial_mass):
            self.evacuation_time = solver.t
        if info["active_set_iterations"]:
            self.iterations.append(info["active_set_iterations"])
        self.steps += 1
        r = self.rho_max
        by_exit = {f"evacuated_{name}": float(v) * r for name, v in zip(solver.exit_names, solver.evacuated_by_exit)}
        return {**by_exit, "time": solver.t, "dt": info["dt"], "mass": d["mass"] * r, "evacuated": d["evacuated"] * r,
                "max_density": d["max_density"] * r, "saturated_area": d["saturated_area"],
                "max_pressure": d["max_pressure"], "active_set_iterations": info["active_set_iterations"],
                "step_seconds": info["step_seconds"], "min_density": d["min_density"] * r,
                "min_pressure": d["min_pressure"], "complementarity": d["complementarity"],
                "linear_residual": info["linear_residual"]}

    def summary(self, solver):
        r, e = self.rho_max, self.extremes
        remaining = solver.mass / self.initial_mass if self.initial_mass > 0 else 0.0
        return {
            "steps": self.steps, "final_time": solver.t,
            "initial_mass": self.initial_mass * r, "final_mass": solver.mass * r,
            "evacuated": solver.evacuated * r,
            "evacuated_by_exit": {name: float(v) * r for name, v in zip(solver.exit_names, solver.evacuated_by_exit)},
            "mass_error": abs(solver.mass + solver.evacuated - self.initial_mass) / max(self.initial_mass, 1e-300),
            "max_mass_error": e["max_mass_error"],
            "min_density_ever": e["min_density"] * r, "max_density_ever": e["max_density"] * r,
            "min_pressure_ever": e["min_pressure"], "max_pressure_ever": e["max_pressure"],
            "max_pressure_unsaturated": e["max_pressure_unsaturated"],
            "max_complementarity": e["max_complementarity"],
            "max_linear_residual": e["max_linear_residual"],
            "active_set_iterations": {
                "mean": float(np.mean(self.iterations)) if self.iterations else 0.0,
                "max": e["max_active_set_iterations"], "steps_with_projection": len(self.iterations)},
            "remaining_fraction": remaining,
            "evacuation_time": self.evacuation_time,
            "non_finite_values": e["non_finite"],
        }
