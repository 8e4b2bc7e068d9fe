"""What a case will do (``femcrowd info``): mesh statistics, the Plan of the run that ``femcrowd run`` checks
(driver/limits.py) and, for a macro case, its run time from a few timed steps of the real solver; nothing
written."""

import tempfile

import numpy as np

from ..case import Case
from ..timer import Stopwatch
from .limits import LimitError
from .macro_model import MacroModel
from .output import FrameSeries
from .run import Simulation

#: timed transport steps of ``femcrowd info``
TIMED_CALLS = 20


def estimate(model: MacroModel, plan: dict) -> dict:
    """Run time of a macro model whose Plan (driver/limits.py: dt, steps, frames) is `plan` (sets its
    projection's warm start: use a fresh model).

    Steps: end / dt with dt = cfl * (CFL-1 step of the upwind scheme) or the
    fixed dt (fewer when the room empties first), as the run's Plan has them. Time per step is measured
    on the scene's solver: a 'free' step is the transport step (no cell over
    saturation, nothing to project); a 'congested' step adds the projection
    of the initial crowd's cells pushed 5 % over saturation, warm-started as
    in a run. The run time lies between all-free and all-congested, plus the
    frames (one frame timed).
    """
    solver, state = model.solver, model.state
    dt, steps, frames = plan["dt"], plan["steps"], plan["frames"]
    crowd = state.density > 0
    congested_input = np.where(crowd, 1.05, 0.0)
    with tempfile.TemporaryDirectory() as tmp:
        clock = Stopwatch()
        FrameSeries(tmp, "solution").write(0.0, model.frame())
        frame_seconds = clock.seconds
    exits = model.scene.boundary.at(state.t)
    transport = solver.transports(state, exits)[0]
    free = _median_seconds(lambda: transport.step(state.density, dt), TIMED_CALLS)
    projection = 0.0
    if crowd.any() and solver.needs_projection:   # (a speed law with f(1) = 0 never projects)
        project = solver.projection(exits)
        project(congested_input)  # cold start: builds the active set
        projection = _median_seconds(lambda: project(congested_input), 3)
    return {"free_step_seconds": free, "congested_step_seconds": free + projection,
            "congested_cells": int(crowd.sum()), "frame_seconds": frame_seconds,
            "seconds": (steps * free + frames * frame_seconds,
                        steps * (free + projection) + frames * frame_seconds)}


def _median_seconds(call, repeat):
    """Median wall time of a call (robust to a busy machine)."""
    durations = []
    for _ in range(repeat):
        clock = Stopwatch()
        call()
        durations.append(clock.seconds)
    return float(np.median(durations))


def case_info(case: Case) -> dict:
    """Resolved configuration, mesh statistics, the run's Plan (driver/limits.py, what `femcrowd run` checks) and
    (macro) its run time; a case beyond the limits is set up only as far as its Plan allows ("over": why)."""
    info = {"case_file": str(case.file), "config": case.config}
    try:
        simulation = Simulation(case)
    except LimitError as err:
        info.update(plan=err.plan.values, over=str(err))
        if err.plan.scene is not None:
            info["mesh"], info["exits"] = err.plan.scene.domain.statistics(), list(err.plan.scene.domain.exit_group)
        return info
    domain = simulation.scene.domain
    info.update(mesh=domain.statistics(), exits=list(domain.exit_group), plan=simulation.plan.values)
    if case["model"]["type"] == "macro":
        info["estimate"] = estimate(simulation.model, simulation.plan.values)
    return info
