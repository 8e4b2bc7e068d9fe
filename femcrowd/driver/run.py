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
from ..mesh import Domain, file_checksum
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
    raises InputError here, before any output directory is touched.
    """

    def __init__(self, case: Case):
        self._wall = time.perf_counter()
        self.case = case
        self.scene = build_scene(case)
        self.model = MODELS[case["model"]["type"]](self.scene)
        log.info("set up %s: %s", case.file, ", ".join(f"{k} {v:.3g} s" for k, v in self.scene.timing.items()))

    def run(self, out=None, force: bool = False, quiet: bool = True, stops=(), on_stop=None,
            stop_when_empty: bool = True) -> Result:
        """Run to time.end (or until the crowd has left), writing into `out` when it is given.

        out: the output directory (relative to the current directory), or None for no files;
        stops, on_stop: times at which to call on_stop(recorder) (studies); stop_when_empty=False runs to
        time.end even when the crowd has left. Returns the Result; summary["status"] is
        "completed", or "interrupted" / "failed: ..." when the loop raised (the exception goes
        on, after the summary is written).
        """
        case, model = self.case, self.model
        model.stop_when_empty &= stop_when_empty
        out_dir = prepare_output_dir(out, case.file, force) if out is not None else None
        history = frames = None
        recorder = Recorder(model.columns)
        measured = model.measurements.recorder if model.measurements is not None else None
        sinks = []
        if out_dir is not None:
            copy_case(case.file, out_dir)
            frames = FrameSeries(out_dir, model.stem)
            history = recorder.sink = HistoryFile(out_dir / "history.csv", recorder.history_columns)
            sinks.append(history)
            if measured is not None:   # the rows recorded so far (t = 0) first, then one per step
                measured.sink = HistoryFile(out_dir / "measurements.csv", measured.history_columns)
                for row in zip(*measured.rows.values()):
                    measured.sink.append(dict(zip(measured.rows, row)))
                sinks.append(measured.sink)
            extra = model.open_files(out_dir)   # e.g. the disc trajectories
            sinks += extra
        domain = self.scene.domain
        summary = {"femcrowd": __version__, "status": "running", "case": case.config,
                   "case_file": str(case.file), "output_dir": str(out_dir) if out_dir else None,
                   "mesh": {"file": str(domain.source), "sha256": file_checksum(domain.source),
                            **domain.statistics()}}
        timers = {"output": 0.0}

        def write_frame():
            if frames is not None:
                tic = time.perf_counter()
                frames.write(model.t, model.frame())
                timers["output"] += time.perf_counter() - tic

        def finish(status):
            for sink in sinks:
                sink.close()
            recorded = recorder.summary()
            summary.update(status=status, **recorded, **model.summary(recorded))
            summary["timing"] = {**self.scene.timing, **dict(model.timers), **timers,
                                 "wall": time.perf_counter() - self._wall}
            if out_dir is not None:
                write_json(out_dir / "summary.json", summary)
            return Result(summary, recorder.history(), model, out_dir,
                          measured.history() if measured is not None else None)

        try:
            drive(model, recorder, case["time"]["end"], case["output"]["every"], write_frame,
                  stops, on_stop, quiet, timers)
        except KeyboardInterrupt:
            finish("interrupted")
            raise
        except Exception as err:
            finish(f"failed: {type(err).__name__}: {err}")
            raise
        return finish("completed")


def run(case: Case, out=None, force: bool = False, quiet: bool = True, files: bool = True) -> Result:
    """Run a case into `out` (relative to the current directory; default: output.dir of the case,
    relative to the case file), or without writing anything when files is False."""
    simulation = Simulation(case)
    return simulation.run(case.output_dir(out) if files else None, force, quiet)
