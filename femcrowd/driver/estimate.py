"""What a case will do (``femcrowd info``): mesh statistics and an estimate of the run from a few
timed steps of the real solver, nothing written."""

import math
import tempfile

import numpy as np

from ..case import Case
from ..mesh import load_domain
from ..timer import Stopwatch
from .macro_model import MacroModel
from .output import FrameSeries
from .scene import build_scene

#: timed transport steps of ``femcrowd info``
TIMED_CALLS = 20


def estimate(model: MacroModel) -> dict:
    """Steps and run time of a macro model (sets its projection's warm start: use a fresh model).

    Steps: end / dt with dt = cfl * (CFL-1 step of the upwind scheme) or the
    fixed dt (fewer when the room empties first). Time per step is measured
    on the scene's solver: a 'free' step is the transport step (no cell over
    saturation, nothing to project); a 'congested' step adds the projection
    of the initial crowd's cells pushed 5 % over saturation, warm-started as
    in a run. The run time lies between all-free and all-congested, plus the
    frames (one frame timed).
    """
    case, solver, state = model.scene.case, model.solver, model.state
    end = case["time"]["end"]
    dt = solver.stable_dt(state)
    steps = math.ceil(end / dt) if math.isfinite(dt) else 1
    crowd = state.density > 0
    congested_input = np.where(crowd, 1.05, 0.0)
    frames = math.floor(end / case["output"]["every"] + 1e-9) + 1
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
    return {"dt": dt, "steps": steps, "frames": frames, "free_step_seconds": free,
            "congested_step_seconds": free + projection, "congested_cells": int(crowd.sum()),
            "frame_seconds": frame_seconds,
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
    """Resolved configuration, mesh statistics and (macro) run estimate of a loaded case."""
    info = {"case_file": str(case.file), "config": case.config}
    if case["model"]["type"] == "macro":
        scene = build_scene(case)
        info["mesh"] = scene.domain.statistics()
        info["exits"] = list(scene.domain.exit_group)
        info["estimate"] = estimate(MacroModel(scene))
    else:
        domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"],
                             case["mesh"]["refine"], case.file)
        info["mesh"], info["exits"] = domain.statistics(), list(domain.exit_group)
    return info
