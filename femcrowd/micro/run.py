"""Micro controller: a case with ``model.type = "micro"`` -> discs -> catching-up steps -> outputs.

The scene (mesh, exits, desired velocity U, initial density) is set up exactly
as for the macro model (:mod:`femcrowd.run`); walls and obstacles are the
mesh's wall facets, exits its exit facets. The discs come from
``[micro].positions`` (CSV with x, y, r) or are sampled without overlap from
``[initial]`` (count from ``[micro].count``, else from the density at the
hexagonal packing density). Time step: ``time.dt``, else
tau = cfl * r_min / max|U| (a disc moves at most cfl radii per step).
"""

import time

import meshio
import numpy as np

from .. import __version__
from ..errors import InputError
from ..mesh import file_checksum, load_domain
from ..output import FrameSeries, History, copy_case, prepare_output_dir, write_json
from ..run import desired_velocity, drive, initial_density
from .sampling import read_discs_csv, sample_discs
from .scheme import MicroSimulation

HISTORY_COLUMNS = ["time", "dt", "count", "evacuated", "contacts", "max_overlap",
                   "solver_iterations", "step_seconds", "kkt"]


def setup_micro(case):
    """Domain, desired velocity and discs of a micro case -> MicroSimulation (nothing written)."""
    domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"],
                         case["mesh"]["refine"], case.file)
    velocity = desired_velocity(case, domain)
    q, r = initial_discs(case, domain)
    speed = np.hypot(*velocity.at_cells(0.0).T).max()
    tau = case["time"]["dt"]
    if tau is None:
        tau = case["time"]["cfl"] * r.min() / speed if speed > 0 else case["output"]["every"]
    sim = MicroSimulation(q, r, domain.boundary_segments("wall"), domain.boundary_segments("exit"),
                          velocity.at_points, tau, method=case["micro"]["method"])
    return domain, sim


def initial_discs(case, domain):
    """(q, r): from the CSV of [micro].positions, or sampled from the initial density."""
    spec = case["micro"]
    if spec["positions"] is not None:
        try:
            q, r = read_discs_csv(case.path(spec["positions"]))
        except (OSError, ValueError) as err:
            raise InputError(case.file, "micro.positions", spec["positions"],
                             getattr(err, "strerror", None) or str(err)) from None
        outside = domain.locate(q) < 0
        if outside.any():
            raise InputError(case.file, "micro.positions", spec["positions"],
                             f"{outside.sum()} disc centres lie outside the domain "
                             f"(first: {q[outside][0].tolist()})")
        return q, r
    rho = initial_density(case, domain)  # cell values, scaled to [0, 1]
    q, r = sample_discs(lambda xy: rho[np.maximum(domain.locate(xy), 0)], domain.points,
                        domain.triangles, spec["radius"], spec["count"],
                        walls=domain.boundary_segments("wall"), exits=domain.boundary_segments("exit"),
                        seed=spec["seed"])
    if len(q) == 0:
        raise InputError(case.file, "initial.density", case["initial"]["density"],
                         "gives no discs (an empty crowd)")
    return q, r


def disc_frame(info_or_sim):
    """A meshio point cloud of the discs with radius, velocity (3 components), pressure."""
    q, r, u, p = (info_or_sim.q, info_or_sim.r, info_or_sim.u, info_or_sim.pressure)
    points = np.column_stack([q, np.zeros(len(q))])
    return meshio.Mesh(points, [("vertex", np.arange(len(q)).reshape(-1, 1))],
                       point_data={"radius": r, "velocity": np.column_stack([u, np.zeros(len(q))]),
                                   "pressure": p})


def run_micro(case, out=None, force=False, quiet=False):
    """Run a micro case: discs.pvd + vtu frames, history.csv, summary.json. Returns the summary."""
    wall = time.perf_counter()
    domain, sim = setup_micro(case)
    out_dir = prepare_output_dir(case.path(out or case["output"]["dir"]), case.file, force)
    copy_case(case.file, out_dir)
    frames = FrameSeries(out_dir, "discs")
    history = History(out_dir / "history.csv", HISTORY_COLUMNS)
    tau, r_min, initial = sim.tau, float(sim.r.min()), sim.count
    state = {"last": None, "steps": 0, "max_overlap": 0.0, "kkt": 0.0, "iterations": [],
             "outside": 0, "evacuation_time": None}
    can_empty = case["time"]["stop_when_empty"] and domain.exit.any()
    summary = {"femcrowd": __version__, "status": "running", "case": case.config,
               "case_file": str(case.file), "output_dir": str(out_dir),
               "mesh": {"file": str(domain.source), "sha256": file_checksum(domain.source),
                        **domain.statistics()},
               "tau": tau, "initial_count": initial}

    def advance(until):
        sim.tau = min(tau, until - sim.t)
        info = sim.step()
        if until - sim.t < 1e-12 * max(1.0, until):
            sim.t = until  # land exactly on the frame time
        sim.tau = tau
        history.append(info.row())
        state.update(last=info, steps=state["steps"] + 1)
        state["max_overlap"] = max(state["max_overlap"], info.max_overlap)
        state["kkt"] = max(state["kkt"], info.kkt)
        state["iterations"].append(info.solver_iterations)
        state["outside"] = max(state["outside"], int(np.count_nonzero(domain.locate(info.q) < 0)))
        if info.count == 0 and state["evacuation_time"] is None and domain.exit.any():
            state["evacuation_time"] = sim.t
        return can_empty and info.count == 0

    def write_frame():
        last = state["last"]
        if last is None:  # t = 0: desired velocities, no contact forces yet
            frames.write(sim.t, disc_frame(_Initial(sim)))
        else:
            frames.write(sim.t, disc_frame(last))

    def finish(status):
        history.close()
        iterations = state["iterations"] or [0]
        summary.update(status=status, steps=state["steps"], final_time=sim.t, final_count=sim.count,
                       evacuated=sim.evacuated, evacuation_time=state["evacuation_time"],
                       max_overlap=state["max_overlap"], max_overlap_over_radius=state["max_overlap"] / r_min,
                       discs_outside=state["outside"], max_kkt=state["kkt"],
                       solver_iterations={"mean": float(np.mean(iterations)), "max": int(np.max(iterations))},
                       timing={"wall": time.perf_counter() - wall})
        write_json(out_dir / "summary.json", summary)
        return summary

    return drive(lambda: sim.t, advance, write_frame, finish, case["time"]["end"],
                 case["output"]["every"], quiet)


class _Initial:
    """The initial state in the shape of a StepInfo, for the first frame."""

    def __init__(self, sim):
        self.q, self.r = sim.q, sim.r
        self.u = sim.desired_velocity() if sim.count else np.zeros((0, 2))
        self.pressure = np.zeros(sim.count)
