"""Where a run writes as it goes (the output sink of Simulation.run): the case copy, the frames, history.csv,
measurements.csv, the model's own files (disc trajectories), the checkpoints and summary.json; or nothing at
all, for a run without an output directory (the Python API, the studies)."""

from pathlib import Path

from . import checkpoint
from .output import FrameSeries, HistoryFile, prepare_output_dir, write_json


class RunFiles:
    """The files of a run in `directory` (None: nothing written). `position`: where a resumed run's checkpoint
    left off (its frames); timing(): the phases' seconds so far, for the checkpoints. Its own seconds go to the
    timer's "output"."""

    def __init__(self, directory, case, model, recorder, identity: dict, timer, timing, position=None,
                 resume: bool = False):
        self.directory, self.model, self.recorder = directory, model, recorder
        self.identity, self.timer, self.timing = identity, timer, timing
        self.frames, self.sinks = None, []
        if directory is None:
            return
        (directory / "case.toml").write_text(case.resolved_toml(directory))   # runs again on its own
        self.frames = FrameSeries(directory, model.stem, (position or {}).get("frames"))
        recorder.sink = HistoryFile(directory / "history.csv", recorder.history_columns, recorder.records())
        self.sinks.append(recorder.sink)
        measured = model.measurements.recorder if model.measurements is not None else None
        if measured is not None:   # the rows recorded so far first, then one per step
            measured.sink = HistoryFile(directory / "measurements.csv", measured.history_columns, measured.records())
            self.sinks.append(measured.sink)
        self.sinks += model.open_files(directory, resume)   # e.g. the disc trajectories

    @classmethod
    def open(cls, out, case, model, recorder, identity, timer, timing, force=False, resume=False):
        """The files of a new run in `out` (relative to the current directory; None: no files), or of the run whose
        checkpoint is there (resume: the model and the record continue from it). Returns (files, position)."""
        position = {}
        if resume:   # checked before anything is written
            state, rows, position = checkpoint.read(out, identity)
            checkpoint.restore(out, case, model, recorder, state, rows)
            directory = Path(out)
        else:
            directory = prepare_output_dir(out, case.file, force) if out is not None else None
        return cls(directory, case, model, recorder, identity, timer, timing, position, resume), position

    def frame(self) -> None:
        """The model's frame at its time."""
        if self.frames is not None:
            with self.timer("output"):
                self.frames.write(self.model.t, self.model.frame())

    def checkpoint(self, next_frame: int) -> None:
        """Everything to continue from here (checkpoint.py)."""
        if self.directory is not None:
            with self.timer("output"):
                checkpoint.write(self.directory, self.identity, self.model.snapshot(), self.recorder.rows,
                                 {"frames": self.frames.frames, "next_frame": next_frame, "timing": self.timing()})

    def close(self) -> None:
        with self.timer("output"):
            for sink in self.sinks:
                sink.close()

    def summary(self, summary: dict) -> None:
        if self.directory is not None:
            write_json(self.directory / "summary.json", summary)
