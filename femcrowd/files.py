"""Writing a file whole or not at all: every file femcrowd writes goes through ``replaced``.

- A file is written under a name of its own next to its target (``.STEM.<12 hex digits>.tmp.SUFFIX``: the
  writer still sees the format's suffix; created with O_EXCL, so never through a link and never another
  writer's), checked (not empty; for the formats whose writers may not report a failed write, gmsh and VTK,
  their closing bytes), flushed to the disk where a lost file costs more than a rerun (fsync: meshes,
  summaries, the tables of studies; not the frames, checkpoints and pictures written again and again) and
  moved onto its name (os.replace): a reader never sees half a file, and a write that fails leaves the file
  it was to replace as it was.
- No write follows a symbolic link: a link at a file's name is refused, and so is a link as a directory
  femcrowd names itself (``plots/``); a directory the user names (--out, -o) may be a link.
- A write that fails (disk full, permissions, a read-only file system) is one line naming the file
  (InputError, exit 2); its temporary file is removed.
"""

import errno
import os
import re
import uuid
from contextlib import contextmanager, suppress
from pathlib import Path

from .errors import InputError

#: the temporary files of replaced() (left behind only by a killed process)
TEMPORARY = ".*." + "?" * 12 + ".tmp*"
LINK = "it is a symbolic link (femcrowd writes no file through a link)"
#: the closing bytes of the formats whose writers do not report a failed write (gmsh, VTK) or whose end is
#: cheap to check, as a pattern of the file's last bytes: a file cut short (a full disk) does not match
ENDINGS = {".msh": rb"\$End[A-Za-z]+\s*", ".vtu": rb"</VTKFile>\s*", ".pvd": rb"</VTKFile>\s*",
           ".png": rb"IEND\xaeB`\x82", ".gif": rb";"}
TAIL = 64


@contextmanager
def writing(path):
    """An OSError in the block (disk full, permissions, a read-only file system, a link where femcrowd
    opens without following links) becomes one line naming `path` (InputError)."""
    try:
        yield
    except OSError as err:
        reason = LINK if err.errno == errno.ELOOP else err.strerror or str(err)
        raise InputError(path, None, None, f"cannot write: {reason}") from None


def complete(path) -> bool:
    """Does the file end as its format ends (ENDINGS; any other format: is it not empty)?"""
    path = Path(path)
    with open(path, "rb") as f:
        size = f.seek(0, os.SEEK_END)
        f.seek(max(0, size - TAIL))
        tail = f.read()
    ending = ENDINGS.get(path.suffix.lower())
    return size > 0 and (ending is None or re.search(ending + rb"\Z", tail) is not None)


@contextmanager
def replaced(path, sync=False):
    """Write `path` anew: the block gets the Path of an empty file of its own next to it (the module), which
    is checked (complete()), synced to the disk (sync) and moved onto `path` when the block ends, removed if
    the block or the check fails. A symbolic link at `path` is refused. Created with O_EXCL; not
    tempfile.mkstemp, whose files are private (0600): these get the user's umask like any file."""
    path = Path(path)
    if path.is_symlink():
        raise InputError(path, None, None, f"cannot write: {LINK}")
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.tmp{path.suffix}")
    with writing(path):
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666))
        try:
            yield tmp
            if not complete(tmp):
                raise InputError(path, None, None, f"cannot write: the file came out incomplete "
                                 f"({tmp.stat().st_size} bytes){_full(tmp)}; the previous one is kept")
            if sync:
                _fsync(tmp)
            os.replace(tmp, path)
            if sync:
                _fsync(path.parent)
        except BaseException:
            with suppress(OSError):
                tmp.unlink()
            raise


def _full(path) -> str:
    """': No space left on device' when the file system of `path` is full."""
    with suppress(OSError):
        if os.statvfs(path.parent).f_bavail == 0:
            return f": {os.strerror(errno.ENOSPC)}"
    return ""


def _fsync(path) -> None:
    fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_text(path, text: str, sync=False) -> None:
    """A text file, whole or not at all (replaced)."""
    with replaced(path, sync) as tmp:
        tmp.write_text(text)


def save_figure(fig, path, dpi=110) -> Path:
    """A matplotlib figure as a picture, whole or not at all (replaced, not synced); returns `path`."""
    with replaced(path) as tmp:
        fig.savefig(tmp, dpi=dpi)
    return Path(path)


def appending(path, newline=None):
    """`path` (just written with replaced()) open to add to its end, never through a link."""
    with writing(path):
        return os.fdopen(os.open(path, os.O_WRONLY | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC), "a",
                         newline=newline)


def make_directory(path, own=False) -> Path:
    """`path` made a directory (with its parents) if missing, a failure one line. own: a directory femcrowd names
    itself (``plots/``), refused if it is a symbolic link (a directory the user names, -o, may be one)."""
    path = Path(path)
    if own and path.is_symlink():
        raise InputError(path, None, None, f"cannot write: {LINK}")
    with writing(path):
        path.mkdir(parents=True, exist_ok=True)
    return path
