"""The progress bar of a study (studies/execute.py, Progress): runs done of the total, the failed ones, on stderr
as a run's bar, the study's lines printed above it."""

import io
import re
import shutil

import pytest
from tqdm import tqdm

import femcrowd.studies.execute as execute
from femcrowd.errors import StudyFailed
from femcrowd.studies.sweep import sweep

from ..support import CASES


def three_members(tmp_path, quiet, monkeypatch):
    """A serial sweep of the corridor on a file that is no mesh (it fails), on its mesh and on a copy of it; the
    bar drawn at every change (no delay, no minimum interval: no clock decides what is drawn) into one buffer
    with the study's lines. Returns what the buffer holds."""
    screen = io.StringIO()
    monkeypatch.setattr(execute, "tqdm", lambda **options: tqdm(**{**options, "delay": 0, "mininterval": 0,
                                                                     "miniters": 1, "file": screen}))
    (tmp_path / "bad.msh").write_text("not a mesh\n")
    mesh = CASES.parent / "meshes" / "corridor.msh"
    shutil.copy(mesh, tmp_path / "copy.msh")
    meshes = f'mesh.file=["{tmp_path / "bad.msh"}", "{mesh}", "{tmp_path / "copy.msh"}"]'
    with pytest.raises(StudyFailed, match="1 of 3"):
        sweep(CASES / "corridor-wall", [meshes], tmp_path / "sweep", ["time.end=0.2", "output.every=0.2"],
              serial=True, echo=lambda line: screen.write(line + "\n"), quiet=quiet)
    return screen.getvalue()


def test_a_study_counts_its_runs_and_the_failed_ones(tmp_path, monkeypatch):
    """0/3 at the start, then 1/3 with one failed, 2/3, 3/3: each drawn again under the line of its run."""
    screen = three_members(tmp_path, False, monkeypatch)
    shown = [part.strip() for part in re.split(r"[\r\n]", screen) if part.strip()]
    counts = [(m[1], m[2]) if (m := re.search(r"\| (\d)/3 runs(?:, (\d) failed)? \[", part)) else part[:9]
              for part in shown]
    lines = [c for c in counts if isinstance(c, str)]
    assert lines == ["failed: m", "done: mes", "done: mes"], shown
    # every line is followed by the bar redrawn with the count of the runs including its own
    assert counts == [("0", None),
                      ("1", "1"), "failed: m", ("1", "1"),
                      ("2", "1"), "done: mes", ("2", "1"),
                      ("3", "1"), "done: mes", ("3", "1"),
                      ("3", "1")], shown   # closed: the bar left as it ended


def test_quiet_shows_the_lines_and_no_bar(tmp_path, monkeypatch):
    screen = three_members(tmp_path, True, monkeypatch)
    assert [line[:9] for line in screen.splitlines()] == ["  failed:", "  done: m", "  done: m"], screen
