"""One run of a case, for either model: set-up, the time loop, the record and (optionally) the files.

This is the Python API as well as what ``femcrowd run`` calls::

    import femcrowd
    case = femcrowd.load_case("cases/room", ["time.end=5"])
    result = femcrowd.Simulation(case).run()          # nothing written
    result.history["mass"], result.state.rho          # arrays
    femcrowd.run(case, out="results/room")           # frames, history.csv, summary.json
"""

import logging
from dataclasses import dataclass
from pathlib import Path

from .. import __version__
from ..case import Case
from ..errors import InputError
from ..linalg.threads import thread_limit
from ..mesh import Domain, file_checksum
from ..timer import Stopwatch, Timer
from . import checkpoint
from .limits import LIMITS, Limits, Plan
from .loop import Controller, Stalled
from .macro_model import MacroModel
from .micro_model import MicroModel
from .recorder import Recorder
from .scene import build_scene
from .sink import RunFiles

log = logging.getLogger("femcrowd")

MODELS = {"macro": MacroModel, "micro": MicroModel}


@dataclass
class Result:
    """A finished (or interrupted) run: its summary, its history (one array per column), the model
    (``state``: the final MacroState, or the MicroSimulation with the discs left) and where its files are."""

    summary: dict
    history: dict
    model: object
    output_dir: Path = None
    measurements: dict = None   # measurements.csv as arrays, for a case with [measure] lines or areas

    @property
    def state(self):  # MacroState, or the MicroSimulation
        return self.model.state

    @property
    def domain(self) -> Domain:
        return self.model.domain


class Simulation:
    """A case set up for a run: the scene and the model's initial state; nothing written yet.

    Building it checks the whole case (mesh, exits, expressions, initial crowd): a bad case
    raises InputError here, before any output directory is touched; so does a run that plans more
    than `limits` allow (``plan``: frames, steps, memory, disk; driver/limits.py; None: no limits).
    ``threads``: the size of the BLAS and OpenMP thread pools during the set-up and the run
    (threadpoolctl). The default, 1, is femcrowd's best choice on a shared machine: its work is
    sparse (mat-vecs, CHOLMOD's supernodes of a 2-D mesh), where more threads gain little and spin
    against other processes (docs/performance.md, "Threads").
    """

    def __init__(self, case: Case, threads: int = 1, limits: Limits | None = LIMITS):
        self._wall = Stopwatch()
        self.case, self.threads = case, threads
        self.timer = Timer()   # the run's own phases: output and recording (the model times its steps)
        self.plan = Plan(case, limits)   # each stage checked before it is done (LimitError)
        with thread_limit(threads):
            self.threads_seconds = self._wall.seconds  # finding the pools, once per process
            self.scene = build_scene(case, self.plan)   # the mesh's size, before refining
            with self.scene.timer("setup"):   # the model's set-up, its own phases (discs, assembly) apart
                self.plan.speeds(self.scene)
                self.plan.discs(self.scene)
                self.model = MODELS[case["model"]["type"]](self.scene)
                self.plan.run(self.model)
        log.info("set up %s: %s", case.file, ", ".join(f"{k} {v:.3g} s" for k, v in self.scene.timer.items()))

    def run(self, out=None, force: bool = False, quiet: bool = True, stops=(), on_stop=None,
            stop_when_empty: bool = True, resume: bool = False) -> Result:
        """Run to time.end (or until the crowd has left), writing into `out` when it is given.

        out: the output directory (relative to the current directory), or None for no files;
        stops, on_stop: times at which to call on_stop(recorder) (studies); stop_when_empty=False runs to
        time.end even when the crowd has left; resume: continue the run whose checkpoint is in `out`
        (checkpoint.py). Returns the Result; summary["status"] is "completed", or "interrupted" /
        "failed: ..." when the loop raised (the exception goes on, after the summary is written), or
        "stopped: ..." when a step could not advance t (then an InputError naming the key responsible).
        """
        case, model, domain = self.case, self.model, self.scene.domain
        model.evacuation.stop &= stop_when_empty
        with self.timer("output"):   # the mesh's checksum and statistics, the output directory
            mesh = {"file": str(domain.source), "sha256": file_checksum(domain.source), **domain.statistics()}
            recorder = Recorder(model.columns)
            files, position = RunFiles.open(out, case, model, recorder,
                                            checkpoint.identity(case.config, mesh["sha256"], case["model"]["type"]),
                                            self.timer, lambda: self._timing(position), force, resume)
        summary = {"femcrowd": __version__, "status": "running", "case": case.config, "case_file": str(case.file),
                   "output_dir": str(files.directory) if files.directory else None, "mesh": mesh}
        controller = Controller(case["time"]["end"], case["output"]["every"], stops, on_stop, quiet)
        try:
            with thread_limit(self.threads):
                controller.run(model, recorder, files, self.timer, position.get("next_frame"))
        except KeyboardInterrupt:
            self._finish(files, recorder, summary, "interrupted", position)
            raise
        except Stalled as err:   # a step below the resolution of t: one line, as bad input
            self._finish(files, recorder, summary, f"stopped: {err}", position)
            raise InputError(case.file, *self.plan.steps_key(model), str(err)) from None
        except Exception as err:
            self._finish(files, recorder, summary, f"failed: {type(err).__name__}: {err}", position)
            raise
        return self._finish(files, recorder, summary, "completed", position)

    def _timing(self, position) -> dict:
        """Seconds per phase (summed over the parts of a resumed run) and the wall time."""
        now = {"threads": self.threads_seconds, **dict(self.scene.timer.items()), **dict(self.model.timers.items()),
               **dict(self.timer.items()), "wall": self._wall.seconds}
        before = position.get("timing", {})
        return {k: before.get(k, 0.0) + now.get(k, 0.0) for k in {**before, **now}}

    def _finish(self, files, recorder, summary, status, position) -> Result:
        """Close the files, write summary.json; the Result. A completed run whose files cannot be closed (their last
        rows written) ends as failed, with that error."""
        try:
            files.close(failed=status != "completed")
        except InputError as err:
            self._finish(files, recorder, summary, f"failed: {type(err).__name__}: {err}", position)
            raise
        with self.timer("output"):
            recorded = recorder.summary()
            summary.update(status=status, **recorded, **self.model.summary(recorded))
        summary["timing"] = self._timing(position)
        files.summary(summary)
        measured = self.model.measurements.recorder if self.model.measurements is not None else None
        return Result(summary, recorder.history(), self.model, files.directory,
                      measured.history() if measured is not None else None)


def run(case: Case, out=None, force: bool = False, quiet: bool = True, files: bool = True,
        threads: int = 1, resume: bool = False, limits: Limits | None = LIMITS) -> Result:
    """Run a case into `out` (relative to the current directory; default: output.dir of the case,
    relative to the case file), or without writing anything when files is False; resume: continue
    the interrupted (or shorter) run in that directory from its checkpoint; limits: what the run may
    plan (driver/limits.py; None: no limits)."""
    simulation = Simulation(case, threads, limits)
    return simulation.run(case.output_dir(out) if files else None, force, quiet, resume=resume)
