"""femcrowd plot against a hostile disk and a damaged run directory: links planted in plots/, a full disk, a
read-only directory, a frame missing or cut short, summary.json cut short. Each is one line naming the file,
exit 2, no traceback; nothing written through a link; the pictures there before kept byte for byte."""

import errno
import os
import shutil

import pytest
import pyvista as pv
from click.testing import CliRunner
from matplotlib.figure import Figure

from femcrowd.cli import main
from femcrowd.files import TEMPORARY

from ..support import CASES

PICTURES = ["plot", "-q", "--no-animation", "--times", "0,0.5"]


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def one_line(result, *words):
    assert result.exit_code == 2, (result.output, result.exception)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("femcrowd: error: ") and "Traceback" not in result.output, \
        result.stderr
    for word in words:
        assert str(word) in lines[0], (word, lines[0])


def snapshot(directory):
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


@pytest.fixture(scope="module")
def plotted(tmp_path_factory):
    """A short run (3 frames) with its pictures in plots/ (2 times, no animation)."""
    out = tmp_path_factory.mktemp("head-on") / "out"
    assert invoke("run", CASES / "stress" / "head-on", "--out", out, "-q", "--set", "time.end=0.5").exit_code == 0
    assert invoke(*PICTURES, out).exit_code == 0
    return out


@pytest.fixture
def run(plotted, tmp_path):
    """A copy of the plotted run to damage."""
    return shutil.copytree(plotted, tmp_path / "run")


def test_a_link_planted_in_plots_is_not_written_through(run, tmp_path):
    """plots/curves.png a link to a file outside: refused, the target as it was (before: overwritten)."""
    target = tmp_path / "precious.png"
    target.write_bytes(b"not femcrowd's")
    (run / "plots" / "curves.png").unlink()
    (run / "plots" / "curves.png").symlink_to(target)
    one_line(invoke(*PICTURES, run), run / "plots" / "curves.png", "symbolic link")
    assert target.read_bytes() == b"not femcrowd's"


def test_plots_as_a_link_to_another_directory_receives_nothing(run, tmp_path):
    """plots a link to another directory: refused before any picture (before: every picture written there)."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.rmtree(run / "plots")
    (run / "plots").symlink_to(elsewhere)
    one_line(invoke(*PICTURES, run), run / "plots", "symbolic link")
    assert list(elsewhere.iterdir()) == []


def half_then_enospc(monkeypatch, cls, name, calls):
    """cls.name (a picture writer) writes as before `calls` times, then half a file and ENOSPC (a disk that
    fills up); returns nothing."""
    original, count = getattr(cls, name), [0]

    def write(self, path, *args, **kwargs):
        count[0] += 1
        if count[0] > calls:
            with open(path, "wb") as f:
                f.write(b"\x89PNG half a picture")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return original(self, path, *args, **kwargs)

    monkeypatch.setattr(cls, name, write)


@pytest.mark.parametrize("writer", ["pyvista", "matplotlib"])
def test_a_full_disk_is_one_line_and_keeps_the_pictures(run, monkeypatch, writer):
    """ENOSPC writing the second density picture (pyvista) or curves.png (matplotlib): one line naming it, the
    pictures of the earlier plot byte for byte, no temporary file (before: an OSError traceback)."""
    before = snapshot(run / "plots")
    if writer == "pyvista":
        half_then_enospc(monkeypatch, pv.Plotter, "screenshot", 1)
        name = "density_t0000.50.png"
    else:
        half_then_enospc(monkeypatch, Figure, "savefig", 0)
        name = "curves.png"
    one_line(invoke(*PICTURES, run), run / "plots" / name, "No space left on device")
    assert snapshot(run / "plots") == before and not list((run / "plots").glob(TEMPORARY))


def test_a_picture_cut_short_without_an_error_is_not_kept(run, monkeypatch):
    """A writer that stops half-way and says nothing (VTK's on a full disk): the PNG is checked before it
    replaces the old one."""
    before = snapshot(run / "plots")
    screenshot = pv.Plotter.screenshot

    def half(self, path, *args, **kwargs):
        screenshot(self, path, *args, **kwargs)
        os.truncate(path, os.path.getsize(path) // 2)

    monkeypatch.setattr(pv.Plotter, "screenshot", half)
    one_line(invoke(*PICTURES, run), run / "plots" / "density_t0000.00.png", "incomplete")
    assert snapshot(run / "plots") == before


def test_a_read_only_directory_is_one_line(run, monkeypatch):
    """No permission to create files in plots/ (as root ignores permissions, the creation fails here as the
    kernel would fail it for another user: EACCES): one line naming the picture, the old ones kept."""
    before = snapshot(run / "plots")
    plots, create = str(run / "plots"), os.open

    def denied(path, flags, *args, **kwargs):
        if os.path.dirname(os.path.abspath(path)) == plots and flags & os.O_CREAT:
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return create(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", denied)
    one_line(invoke(*PICTURES, run), run / "plots", "Permission denied")
    assert snapshot(run / "plots") == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a directory without write permission")
def test_a_read_only_directory_by_its_mode_is_one_line(run):
    before = snapshot(run / "plots")
    (run / "plots").chmod(0o555)
    try:
        result = invoke(*PICTURES, run)
    finally:
        (run / "plots").chmod(0o755)
    one_line(result, run / "plots", "Permission denied")
    assert snapshot(run / "plots") == before


@pytest.mark.parametrize("damage", ["missing", "cut short"])
def test_a_damaged_frame_is_one_line_naming_it(run, damage):
    """A frame listed in solution.pvd that is gone or cut short (before: FileNotFoundError, KeyError)."""
    frame = run / "solution_00002.vtu"
    if damage == "missing":
        frame.unlink()
    else:
        os.truncate(frame, frame.stat().st_size // 2)
    one_line(invoke(*PICTURES, run), frame, "frame 2 of solution.pvd (t = 0.5 s)",
             "missing" if damage == "missing" else "incomplete")


def test_a_summary_cut_short_is_one_line(run):
    summary = run / "summary.json"
    os.truncate(summary, summary.stat().st_size // 2)
    one_line(invoke(*PICTURES, run), summary, "not JSON")
