"""The progress bar of a study (studies/execute.py, Progress): runs done of the total, the failed ones, on stderr
as a run's bar, the study's lines printed above it."""

import io
import logging
import re
import shutil

import pytest
from tqdm import tqdm

import femcrowd.studies.execute as execute
from femcrowd.errors import StudyFailed
from femcrowd.studies import rimea, stress
from femcrowd.studies.sweep import sweep

from ..support import CASES


@pytest.fixture
def screen(monkeypatch):
    """One buffer for the bar and the study's lines; the bar drawn at every change (no delay, no minimum
    interval: no clock decides what is drawn)."""
    screen = io.StringIO()
    monkeypatch.setattr(execute, "tqdm", lambda **options: tqdm(**{**options, "delay": 0, "mininterval": 0,
                                                                     "miniters": 1, "file": screen}))
    return screen


def shown(screen, total):
    """What the screen showed, in order: (runs done, failed) of each bar drawn, the first 9 characters of each
    line of the study."""
    parts = [part.strip() for part in re.split(r"[\r\n]", screen.getvalue()) if part.strip()]
    return [(int(m[1]), int(m[2] or 0)) if (m := re.search(rf"\| (\d+)/{total} runs(?:, (\d+) failed)? \[", part))
            else part[:9] for part in parts]


def three_members(tmp_path, screen, quiet):
    """A serial sweep of the corridor on a file that is no mesh (it fails), on its mesh and on a copy of it."""
    (tmp_path / "bad.msh").write_text("not a mesh\n")
    mesh = CASES.parent / "meshes" / "corridor.msh"
    shutil.copy(mesh, tmp_path / "copy.msh")
    meshes = f'mesh.file=["{tmp_path / "bad.msh"}", "{mesh}", "{tmp_path / "copy.msh"}"]'
    with pytest.raises(StudyFailed, match="1 of 3"):
        sweep(CASES / "corridor-wall", [meshes], tmp_path / "sweep", ["time.end=0.2", "output.every=0.2"],
              serial=True, echo=lambda line: screen.write(line + "\n"), quiet=quiet)


def test_a_study_counts_its_runs_and_the_failed_ones(tmp_path, screen):
    """0/3 at the start, then 1/3 with one failed, 2/3, 3/3: each drawn again under the line of its run."""
    three_members(tmp_path, screen, quiet=False)
    assert shown(screen, 3) == [(0, 0),
                                (1, 1), "failed: m", (1, 1),
                                (2, 1), "done: mes", (2, 1),
                                (3, 1), "done: mes", (3, 1),
                                (3, 1)], screen.getvalue()   # closed: the bar left as it ended


def test_quiet_shows_the_lines_and_no_bar(tmp_path, screen):
    three_members(tmp_path, screen, quiet=True)
    assert [line[:9] for line in screen.getvalue().splitlines()] == ["  failed:", "  done: m", "  done: m"]


def test_the_stress_matrix_counts_its_scenes_and_the_failed_ones(tmp_path, screen, monkeypatch):
    """Two scenes, the second made to fail a check of its own: 1/2, then 2/2 with one failed."""
    monkeypatch.setitem(stress.CHECKS, "u-zero", lambda output: [stress.Check("made to fail", False, "")])
    results, _ = stress.run_matrix(tmp_path / "stress", only=("door-one-edge", "u-zero"), quiet=False,
                                   echo=lambda result: screen.write(f"{result.name}\n"))
    assert [r.passed for r in results] == [True, False]
    assert shown(screen, 2) == [(0, 0), (1, 0), "door-one-", (1, 0), (2, 1), "u-zero", (2, 1), (2, 1)]


def test_rimea_counts_every_run_of_its_seeds(tmp_path, screen):
    """Test 10 with the recommended discs over two seeds: two runs, the test's row once both are done."""
    rimea.run_all(("10",), ("micro-recommended",), out=tmp_path, seeds=2, quiet=False,
                  echo=lambda row: screen.write(row + "\n"))
    assert shown(screen, 2) == [(0, 0), (1, 0), (2, 0), "10 alloca", (2, 0), (2, 0)]


def test_log_lines_go_above_the_bar_and_the_handlers_come_back(screen, monkeypatch):
    """A warning of a run while the bar is on: the bar cleared, the line, the bar again (it used to be glued to the
    bar's line); femcrowd's own handlers back after the study."""
    log = logging.getLogger("femcrowd")
    handler = logging.StreamHandler(screen)
    monkeypatch.setattr(log, "handlers", [handler])
    with execute.Progress(2, quiet=False) as progress:
        progress.advance()
        log.warning("a warning of the second run")
        progress.advance()
    assert log.handlers == [handler]
    assert shown(screen, 2) == [(0, 0), (1, 0), "a warning", (1, 0), (2, 0), (2, 0)]
    assert re.search(r"\r *\ra warning of the second run\n\r?study", screen.getvalue()), screen.getvalue()
