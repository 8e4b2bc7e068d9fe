"""One run of a case, for either model: set-up, the time loop, the record and (optionally) the files.

This is the Python API as well as what ``femcrowd run`` calls::

    import femcrowd
    case = femcrowd.load_case("cases/room", ["time.end=5"])
    result = femcrowd.Simulation(case).run()          # nothing written
    result.history["mass"], result.state.rho          # arrays
    femcrowd.run(case, out="results/room")           # frames, history.csv, summary.json
"""

import logging
import time
from dataclasses import dataclass
from pathlib import Path

from .. import __version__
from ..case import Case
from ..linalg.threads import thread_limit
from ..mesh import Domain, file_checksum
from . import checkpoint
from .loop import drive
from .macro_model import MacroModel
from .micro_model import MicroModel
from .output import FrameSeries, HistoryFile, copy_case, prepare_output_dir, write_json
from .recorder import Recorder
from .scene import build_scene

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
    raises InputError here, before any output directory is touched. ``threads``: the size of the
    BLAS and OpenMP thread pools during the set-up and the run (threadpoolctl). The default, 1,
    is femcrowd's best choice on a shared machine: its work is sparse (mat-vecs, CHOLMOD's
    supernodes of a 2-D mesh), where more threads gain little and spin against other processes
    (docs/performance.md, "Threads").
    """

    def __init__(self, case: Case, threads: int = 1):
        self._wall = time.perf_counter()
        self.case, self.threads = case, threads
        with thread_limit(threads):
            self.threads_seconds = time.perf_counter() - self._wall  # finding the pools, once per process
            self.scene = build_scene(case)
            self.model = MODELS[case["model"]["type"]](self.scene)
        log.info("set up %s: %s", case.file, ", ".join(f"{k} {v:.3g} s" for k, v in self.scene.timing.items()))

    def run(self, out=None, force: bool = False, quiet: bool = True, stops=(), on_stop=None,
            stop_when_empty: bool = True, resume: bool = False) -> Result:
        """Run to time.end (or until the crowd has left), writing into `out` when it is given.

        out: the output directory (relative to the current directory), or None for no files;
        stops, on_stop: times at which to call on_stop(recorder) (studies); stop_when_empty=False runs to
        time.end even when the crowd has left; resume: continue the run whose checkpoint is in `out`
        (checkpoint.py). Returns the Result; summary["status"] is "completed", or "interrupted" /
        "failed: ..." when the loop raised (the exception goes on, after the summary is written).
        """
        case, model, domain = self.case, self.model, self.scene.domain
        model.evacuation.stop &= stop_when_empty
        tic = time.perf_counter()
        mesh = {"file": str(domain.source), "sha256": file_checksum(domain.source), **domain.statistics()}
        identity = checkpoint.identity(case.config, mesh["sha256"], case["model"]["type"])
        recorder, position = Recorder(model.columns), {}
        if resume:  # checked before anything is written
            state, rows, position = checkpoint.read(out, identity)
            model.restore(state)
            recorder.restore(rows)
            out_dir = Path(out)
        else:
            out_dir = prepare_output_dir(out, case.file, force) if out is not None else None
        frames = None
        measured = model.measurements.recorder if model.measurements is not None else None
        sinks = []
        if out_dir is not None:
            copy_case(case.file, out_dir)
            frames = FrameSeries(out_dir, model.stem, position.get("frames"))
            history = recorder.sink = HistoryFile(out_dir / "history.csv", recorder.history_columns,
                                                  recorder.records())
            sinks.append(history)
            if measured is not None:   # the rows recorded so far first, then one per step
                measured.sink = HistoryFile(out_dir / "measurements.csv", measured.history_columns,
                                            measured.records())
                sinks.append(measured.sink)
            sinks += model.open_files(out_dir, resume)   # e.g. the disc trajectories
        summary = {"femcrowd": __version__, "status": "running", "case": case.config,
                   "case_file": str(case.file), "output_dir": str(out_dir) if out_dir else None, "mesh": mesh}
        timers = {"output": time.perf_counter() - tic}  # output directory, mesh checksum and statistics

        def timing():
            """Seconds per phase (summed over the parts of a resumed run) and the wall time."""
            now = {"threads": self.threads_seconds, **self.scene.timing, **dict(model.timers), **timers,
                   "wall": time.perf_counter() - self._wall}
            before = position.get("timing", {})
            return {k: before.get(k, 0.0) + now.get(k, 0.0) for k in {**before, **now}}

        def write_frame():
            if frames is not None:
                tic = time.perf_counter()
                frames.write(model.t, model.frame())
                timers["output"] += time.perf_counter() - tic

        def write_checkpoint(next_frame):
            tic = time.perf_counter()
            checkpoint.write(out_dir, identity, model.snapshot(), recorder.rows,
                             {"frames": frames.frames, "next_frame": next_frame, "timing": timing()})
            timers["output"] += time.perf_counter() - tic

        def finish(status):
            tic = time.perf_counter()
            for sink in sinks:
                sink.close()
            recorded = recorder.summary()
            summary.update(status=status, **recorded, **model.summary(recorded))
            timers["output"] += time.perf_counter() - tic
            summary["timing"] = timing()
            if out_dir is not None:
                write_json(out_dir / "summary.json", summary)
            return Result(summary, recorder.history(), model, out_dir,
                          measured.history() if measured is not None else None)

        try:
            with thread_limit(self.threads):
                drive(model, recorder, case["time"]["end"], case["output"]["every"], write_frame,
                      stops, on_stop, quiet, timers, write_checkpoint if out_dir is not None else None,
                      position.get("next_frame"))
        except KeyboardInterrupt:
            finish("interrupted")
            raise
        except Exception as err:
            finish(f"failed: {type(err).__name__}: {err}")
            raise
        return finish("completed")


def run(case: Case, out=None, force: bool = False, quiet: bool = True, files: bool = True,
        threads: int = 1, resume: bool = False) -> Result:
    """Run a case into `out` (relative to the current directory; default: output.dir of the case,
    relative to the case file), or without writing anything when files is False; resume: continue
    the interrupted (or shorter) run in that directory from its checkpoint."""
    simulation = Simulation(case, threads)
    return simulation.run(case.output_dir(out) if files else None, force, quiet, resume=resume)
