"""history.csv is written in blocks (driver/output.py, HistoryFile): the rows kept since the last frame go out
before each frame and checkpoint and at the end, so that what a run leaves (finished, interrupted, or stopped by
a write that fails) holds every row up to its last frame."""

import errno
import json
import os

import numpy as np

from femcrowd.driver import output
from femcrowd.driver.reading import read_history, read_pvd

from .test_output_dir import QUICK, invoke, one_line


def test_every_frame_finds_the_rows_up_to_its_time(tmp_path, monkeypatch):
    """At each frame written, history.csv on disk ends with the row of the frame's time; the finished file has one
    row per step and the initial one, the same as the rows the run kept."""
    out, seen = tmp_path / "out", []
    write = output.FrameSeries.write

    def frame(self, t, mesh):
        seen.append((t, read_history(out / "history.csv")["time"]))
        return write(self, t, mesh)

    monkeypatch.setattr(output.FrameSeries, "write", frame)
    assert invoke("run", QUICK, "--out", out, "-q").exit_code == 0
    assert len(seen) == len(read_pvd(out / "solution.pvd")) > 2
    for t, times in seen:
        assert times[-1] == t and np.all(np.diff(times) > 0)
    history, summary = read_history(out / "history.csv"), json.loads((out / "summary.json").read_text())
    assert len(history["time"]) == summary["steps"] + 1 and history["time"][-1] == summary["final_time"]


def test_rows_that_cannot_be_written_stop_the_run_in_one_line(tmp_path, monkeypatch):
    """ENOSPC the fourth time the rows go out (the checkpoint after the second frame): one line naming history.csv,
    exit 2, summary.json says the run failed, and the rows written before (up to the second frame) are whole."""
    out, calls = tmp_path / "out", [0]
    flush = output.HistoryFile.flush

    def full(self):
        calls[0] += 1
        if calls[0] > 3:
            raise output.InputError(self.path, None, None, f"cannot write: {os.strerror(errno.ENOSPC)}")
        return flush(self)

    monkeypatch.setattr(output.HistoryFile, "flush", full)
    result = invoke("run", QUICK, "--out", out, "-q")
    assert result.exit_code == 2
    one_line(result.stderr, out / "history.csv", "No space left on device")
    assert json.loads((out / "summary.json").read_text())["status"].startswith("failed: InputError")
    times = read_history(out / "history.csv")["time"]
    assert times[-1] == read_pvd(out / "solution.pvd")[1][0] and np.all(np.diff(times) > 0)


def test_a_completed_run_whose_last_rows_fail_ends_failed(tmp_path, monkeypatch):
    """The write of the rows at the close fails (a run that had completed): one line naming history.csv, exit 2,
    summary.json written with the run failed, the rows up to the last frame whole."""
    out = tmp_path / "out"
    flush, close = output.HistoryFile.flush, output.HistoryFile.close

    def closing(self):
        self.closing = True
        return close(self)

    def full(self):
        if getattr(self, "closing", False):
            raise output.InputError(self.path, None, None, f"cannot write: {os.strerror(errno.ENOSPC)}")
        return flush(self)

    monkeypatch.setattr(output.HistoryFile, "flush", full)
    monkeypatch.setattr(output.HistoryFile, "close", closing)
    result = invoke("run", QUICK, "--out", out, "-q")
    assert result.exit_code == 2
    one_line(result.stderr, out / "history.csv", "No space left on device")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"].startswith("failed: InputError")
    last = read_pvd(out / "solution.pvd")[-1][0]
    assert read_history(out / "history.csv")["time"][-1] == last == summary["final_time"]
