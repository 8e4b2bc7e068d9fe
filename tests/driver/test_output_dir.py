"""An output directory is one run's at a time (driver/ownership.py): a second run into it is refused with one line,
a killed run leaves no stuck lock, no write follows a link planted in the directory, a write that fails (disk full,
permissions) is one line with the directory left resumable, and --out may not be the case's own directory."""

import errno
import json
import os
import signal
import subprocess
import time

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd.cli import main
from femcrowd.driver import vtu
from femcrowd.driver.output import MARKER
from femcrowd.driver.ownership import LOCK, RunLock, reading
from femcrowd.driver.reading import read_frame, read_history, read_pvd
from femcrowd.files import TEMPORARY

from ..support import CASES, FEMCROWD

ROOM = CASES / "room"                 # 925 steps, 31 frames: a few seconds
OTHER = CASES / "narrow-door"         # another mesh
QUICK = CASES / "stress" / "head-on"  # 258 steps to 1.5 s, a frame every 0.25 s


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def snapshot(directory):
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(directory.iterdir())}


def one_line(stderr, *words):
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("femcrowd: error: ") and "Traceback" not in stderr, stderr
    for word in words:
        assert str(word) in lines[0], (word, lines[0])


def start(case, out, *args):
    """A `femcrowd run` process, returned once it has written its first frame (it holds the directory)."""
    proc = subprocess.Popen([str(FEMCROWD), "run", str(case), "--out", str(out), "-q", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300   # a bound for a hang, whatever the machine's load
    while not (out / "checkpoint.npz").is_file():
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.02)
    return proc


def test_a_second_run_into_a_busy_directory_is_refused(tmp_path):
    """Another case, and --resume of the same, into the directory of a run under way: one line, exit 2; the
    first run completes with its own files (every frame of its mesh, none deleted, nothing added)."""
    out = tmp_path / "out"
    first = start(ROOM, out)
    others = [subprocess.Popen([str(FEMCROWD), "run", str(case), "--out", str(out), "-q", *args], text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
              for case, args in ((OTHER, []), (ROOM, ["--resume"]))]
    others = [(other, *other.communicate(timeout=120)) for other in others]
    running = first.poll() is None   # (if not, the others may have found the directory free)
    stdout, stderr = first.communicate(timeout=120)
    for other, other_stdout, other_stderr in others:
        assert other.returncode == 2 and other_stdout == "", (running, other_stdout, other_stderr)
        one_line(other_stderr, out, "another femcrowd run")
    assert first.returncode == 0 and stdout.startswith("completed"), stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["mesh"]["file"].endswith("room_one_door.msh")
    frames = read_pvd(out / "solution.pvd")
    assert {p.name for p in out.iterdir()} == {LOCK, MARKER, "case.toml", "checkpoint.npz", "history.csv",
                                               "summary.json", "solution.pvd", *(name for _, name in frames)}
    assert len(frames) == 31
    triangles = {len(read_frame(out / name).cells_dict["triangle"]) for _, name in frames}
    assert triangles == {summary["mesh"]["triangles"]}
    assert len(read_history(out / "history.csv")["time"]) == summary["steps"] + 1


def test_a_killed_run_leaves_no_stuck_lock(tmp_path):
    """SIGKILL holds no lock: the kernel drops it with the process; the next run takes the directory."""
    out = tmp_path / "out"
    first = start(ROOM, out)
    assert (out / LOCK).is_file()
    first.send_signal(signal.SIGKILL)
    first.communicate(timeout=60)
    result = subprocess.run([str(FEMCROWD), "run", str(ROOM), "--out", str(out), "-q", "--set", "time.end=0.5"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert json.loads((out / "summary.json").read_text())["final_time"] == 0.5


def test_the_lock_is_released_and_plot_may_read_a_run_in_progress(tmp_path):
    """In one process: a run's lock is refused to a second run until released; a reader (femcrowd plot)
    shares the directory with a run in progress but not with a run that clears it."""
    out = tmp_path / "out"
    out.mkdir()
    held = RunLock(out).acquire()
    with pytest.raises(Exception, match="another femcrowd run"):
        RunLock(out).acquire()
    with pytest.raises(Exception, match="clearing this directory"):
        with reading(out):
            pass
    held.settled()   # the run under way: plot may read
    with reading(out):
        with pytest.raises(Exception, match="another femcrowd run"):
            RunLock(out).acquire()
    held.release()
    with reading(out):   # plot reading, no run: a new run is refused, the directory untouched
        before = snapshot(out)
        result = invoke("run", QUICK, "--out", out, "-q", "--force")
        assert result.exit_code == 2 and snapshot(out) == before
        one_line(result.stderr, "femcrowd plot is reading")
    RunLock(out).acquire().release()


def plant(out, names, tmp_path):
    """Links in `out` to files outside it; returns {target: its text}."""
    targets = {}
    for name in names:
        target = tmp_path / f"outside-{name.strip('.')}"
        target.write_text(f"not femcrowd's: {name}\n")
        (out / name).unlink(missing_ok=True)
        (out / name).symlink_to(target)
        targets[target] = target.read_bytes()
    return targets


def test_no_write_follows_a_link_on_a_new_run(tmp_path):
    out = tmp_path / "out"
    assert invoke("run", QUICK, "--out", out, "-q", "--set", "time.end=0.25").exit_code == 0
    targets = plant(out, ["checkpoint.npz.tmp", "solution.pvd.tmp", "summary.json.tmp", "history.csv", "case.toml",
                          "summary.json", "solution_00001.vtu"], tmp_path)
    result = invoke("run", QUICK, "--out", out, "-q", "--set", "time.end=0.5")
    assert result.exit_code == 0, result.output
    assert {t: t.read_bytes() for t in targets} == targets
    assert not (out / "history.csv").is_symlink() and json.loads((out / "summary.json").read_text())["steps"] > 0


def test_no_write_follows_a_link_on_resume(tmp_path):
    """history.csv, case.toml, summary.json, the index, the next frame and temporary names as links to files
    outside: --resume replaces the links with its files, the targets are left as they were."""
    out, whole = tmp_path / "out", tmp_path / "whole"
    assert invoke("run", QUICK, "--out", whole, "-q").exit_code == 0
    assert invoke("run", QUICK, "--out", out, "-q", "--set", "time.end=0.5").exit_code == 0
    targets = plant(out, ["history.csv", "case.toml", "summary.json", "solution.pvd", "solution_00003.vtu",
                          "checkpoint.npz.tmp", "summary.json.tmp"], tmp_path)
    result = invoke("run", QUICK, "--out", out, "-q", "--resume")
    assert result.exit_code == 0, result.output
    assert {t: t.read_bytes() for t in targets} == targets
    ha, hb = read_history(out / "history.csv"), read_history(whole / "history.csv")
    assert np.allclose(ha["mass"], hb["mass"], rtol=1e-10) and len(ha["time"]) == len(hb["time"])


def test_a_link_at_a_file_name_is_refused(tmp_path):
    """--force into a directory not written by femcrowd, holding a link named summary.json: the run stops with
    one line naming it (before: the link was replaced), its target untouched."""
    out = tmp_path / "out"
    out.mkdir()
    targets = plant(out, ["summary.json"], tmp_path)
    result = invoke("run", QUICK, "--out", out, "-q", "--force", "--set", "time.end=0.25")
    assert result.exit_code == 2
    one_line(result.stderr, out / "summary.json", "symbolic link")
    assert {t: t.read_bytes() for t in targets} == targets and (out / "summary.json").is_symlink()


def test_a_link_as_the_lock_is_refused(tmp_path):
    out = tmp_path / "out"
    assert invoke("run", QUICK, "--out", out, "-q", "--set", "time.end=0.25").exit_code == 0
    targets = plant(out, [LOCK], tmp_path)
    before = {p.name: p.read_bytes() for p in out.iterdir() if not p.is_symlink()}
    result = invoke("run", QUICK, "--out", out, "-q")
    assert result.exit_code == 2
    one_line(result.stderr, out / LOCK, "symbolic link")
    assert {t: t.read_bytes() for t in targets} == targets
    assert {p.name: p.read_bytes() for p in out.iterdir() if not p.is_symlink()} == before


def full_disk_after(monkeypatch, module, name, calls):
    """module.name writes as before `calls` times, then half a file and ENOSPC (a disk that fills up)."""
    original, count = getattr(module, name), [0]

    def write(target, *args, **kwargs):
        count[0] += 1
        if count[0] > calls:
            path = target if isinstance(target, (str, os.PathLike)) else target.name
            with open(path, "wb") as f:
                f.write(b"half a file")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return original(target, *args, **kwargs)

    monkeypatch.setattr(module, name, write)


@pytest.mark.parametrize("where", ["frame", "checkpoint"])
def test_a_full_disk_stops_the_run_resumable(tmp_path, monkeypatch, where):
    """ENOSPC writing a frame or a checkpoint: one line naming the file, exit 2, no temporary file left, the last
    checkpoint intact; --resume (space freed) gives the uninterrupted run."""
    out, whole = tmp_path / "out", tmp_path / "whole"
    assert invoke("run", QUICK, "--out", whole, "-q").exit_code == 0
    full_disk_after(monkeypatch, vtu if where == "frame" else np, "write" if where == "frame" else "savez", 3)
    result = invoke("run", QUICK, "--out", out, "-q")
    assert result.exit_code == 2
    name = "solution_00003.vtu" if where == "frame" else "checkpoint.npz"
    one_line(result.stderr, out / name, "No space left on device")
    assert not list(out.glob("*.tmp")) and not list(out.glob(TEMPORARY))
    with np.load(out / "checkpoint.npz") as data:   # the one of frame 2, whole
        assert float(data["state/t"]) == 0.5
    monkeypatch.undo()
    result = invoke("run", QUICK, "--out", out, "-q", "--resume")
    assert result.exit_code == 0, result.output
    ha, hb = read_history(out / "history.csv"), read_history(whole / "history.csv")
    assert len(ha["time"]) == len(hb["time"]) and np.allclose(ha["mass"], hb["mass"], rtol=1e-10)
    assert [t for t, _ in read_pvd(out / "solution.pvd")] == [t for t, _ in read_pvd(whole / "solution.pvd")]


@pytest.mark.parametrize("lock", [True, False], ids=["locked-before", "no-lock-file"])
def test_an_unwritable_directory_is_one_line(tmp_path, monkeypatch, lock):
    """A directory without write permission (as root ignores permissions, the calls that need it fail here as
    the kernel would fail them: creating, removing, renaming a file in it): one line naming the directory or the
    file, exit 2, a new run and --resume alike, the earlier run untouched. Its lock file may be there already
    (an earlier run took it) or not (a directory of an older femcrowd)."""
    out = tmp_path / "out"
    assert invoke("run", QUICK, "--out", out, "-q", "--set", "time.end=0.25").exit_code == 0
    if not lock:
        (out / LOCK).unlink(missing_ok=True)
    before = snapshot(out)
    inside = lambda path: os.path.dirname(os.path.abspath(path)) == str(out)  # noqa: E731

    def denied(call, creating=False):
        def refuse(path, *args, **kwargs):
            if inside(path) and (not creating or args[0] & os.O_CREAT and not os.path.exists(path)):
                raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
            return call(path, *args, **kwargs)
        return refuse

    monkeypatch.setattr(os, "open", denied(os.open, creating=True))
    for name in ("unlink", "replace", "rename"):
        monkeypatch.setattr(os, name, denied(getattr(os, name)))
    for args in ([], ["--resume", "--set", "time.end=0.5"]):
        result = invoke("run", QUICK, "--out", out, "-q", *args)
        assert result.exit_code == 2, result.output
        one_line(result.stderr, out, "Permission denied")
        assert snapshot(out) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only directory")
def test_a_read_only_directory_is_one_line(tmp_path):
    out = tmp_path / "out"
    assert invoke("run", QUICK, "--out", out, "-q", "--set", "time.end=0.25").exit_code == 0
    before = snapshot(out)
    out.chmod(0o555)
    try:
        result = subprocess.run([str(FEMCROWD), "run", str(QUICK), "--out", str(out), "-q"], capture_output=True,
                                text=True, timeout=120)
    finally:
        out.chmod(0o755)
    assert result.returncode == 2
    one_line(result.stderr, out, "Permission denied")
    assert snapshot(out) == before


@pytest.mark.parametrize("force", [[], ["--force"]], ids=["plain", "force"])
def test_out_may_not_be_the_case_directory(tmp_path, force):
    case = tmp_path / "case"
    case.mkdir()
    (case / "case.toml").write_text((QUICK / "case.toml").read_text().replace('"../../../meshes/', '"'
                                    + str(CASES.parent / "meshes") + "/"))
    before = snapshot(case)
    result = invoke("run", case, "--out", case, "-q", *force)
    assert result.exit_code == 2
    one_line(result.stderr, case / "case.toml", "the case's own directory")
    assert snapshot(case) == before
