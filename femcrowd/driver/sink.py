"""Where a run writes as it goes (the output sink of Simulation.run): the case copy, the frames, history.csv,
measurements.csv, the model's own files (disc trajectories), the checkpoints and summary.json; or nothing at
all, for a run without an output directory (the Python API, the studies)."""

from pathlib import Path

from ..errors import InputError
from ..files import write_text, writing
from . import checkpoint
from .output import FrameSeries, HistoryFile, own_output_dir, write_json


class RunFiles:
    """The files of a run in `directory` (None: nothing written). `position`: where a resumed run's checkpoint
    left off (its frames); timing(): the phases' seconds so far, for the checkpoints. Its own seconds go to the
    timer's "output"."""

    def __init__(self, directory, case, model, recorder, identity: dict, timer, timing, position=None,
                 resume: bool = False, lock=None):
        self.directory, self.model, self.recorder = directory, model, recorder
        self.identity, self.timer, self.timing, self.lock = identity, timer, timing, lock
        self.frames, self.sinks, self.tables = None, [], []
        if directory is None:
            return
        write_text(directory / "case.toml", case.resolved_toml(directory))   # runs again on its own
        self.frames = FrameSeries(directory, model.stem, (position or {}).get("frames"))
        recorder.sink = HistoryFile(directory / "history.csv", recorder.history_columns, recorder.records())
        self.tables.append(recorder.sink)
        measured = model.measurements.recorder if model.measurements is not None else None
        if measured is not None:   # the rows recorded so far first, then one per step
            measured.sink = HistoryFile(directory / "measurements.csv", measured.history_columns, measured.records())
            self.tables.append(measured.sink)
        self.sinks = [*self.tables, *model.open_files(directory, resume)]   # e.g. the disc trajectories

    @classmethod
    def open(cls, out, case, model, recorder, identity, timer, timing, force=False, resume=False):
        """The files of a new run in `out` (relative to the current directory; None: no files), or of the run whose
        checkpoint is there (resume: the model and the record continue from it). Returns (files, position).
        The directory is the run's from before anything in it changes until summary() (ownership.RunLock)."""
        position, lock = {}, None
        try:
            if resume:   # checked before anything is written
                if (Path(out) / checkpoint.NAME).is_file():   # else read() refuses, nothing created
                    lock = own_output_dir(out, case.file, resume=True)
                state, rows, position = checkpoint.read(out, identity)
                checkpoint.restore(out, case, model, recorder, state, rows)
            elif out is not None:
                lock = own_output_dir(out, case.file, force)
            directory = lock.directory if lock is not None else None
            with writing(directory):
                files = cls(directory, case, model, recorder, identity, timer, timing, position, resume, lock)
        except BaseException:
            if lock is not None:
                lock.release()
            raise
        if lock is not None:
            lock.settled()
        return files, position

    def frame(self) -> None:
        """The rows of the tables so far, and the model's frame at its time."""
        if self.frames is not None:
            with self.timer("output"):
                self.flush()
                self.frames.write(self.model.t, self.model.frame())

    def flush(self) -> None:
        """Write the rows the tables (history.csv, measurements.csv) keep."""
        for table in self.tables:
            table.flush()

    def checkpoint(self, next_frame: int) -> None:
        """Everything to continue from here (checkpoint.py)."""
        if self.directory is not None:
            with self.timer("output"):
                self.flush()
                checkpoint.write(self.directory, self.identity, self.model.snapshot(), self.recorder.rows,
                                 {"frames": self.frames.frames, "next_frame": next_frame, "timing": self.timing()})

    def close(self, failed: bool = False) -> None:
        """Write the rows kept and close the files; a write that fails is one line (InputError), but for a run
        that failed already (failed), which keeps its own error."""
        errors = []
        with self.timer("output"):
            for sink in self.sinks:
                try:
                    sink.close()
                except InputError as err:
                    errors.append(err)
        if errors and not failed:
            raise errors[0]

    def summary(self, summary: dict) -> None:
        """Write summary.json (a failed run keeps its own error if this write fails too), then let the directory
        go: another run may take it."""
        try:
            if self.directory is not None:
                write_json(self.directory / "summary.json", summary)
        except InputError:
            if not summary["status"].startswith("failed"):
                raise
        finally:
            if self.lock is not None:
                self.lock.release()
