"""An output directory belongs to one run at a time, and a run writes only inside it.

- The lock (fcntl.flock, which the kernel releases when its process ends, however it ends: a crashed or
  SIGKILLed run leaves no stale lock; the file, empty, is never deleted: deleting a lock file races with
  whoever has just opened it). A run holds DIR/.femcrowd-lock exclusively from before it changes
  anything in the directory until its summary is written: a second run into it is refused with one line.
  While the run clears the directory (the files of an earlier run; on --resume, the frames after the
  checkpoint) it holds the directory itself exclusively too; ``femcrowd plot`` holds the directory shared
  while it reads, so that a new run does not pull files from under a plot, while a run in progress may
  be plotted (it only adds files, or replaces them whole).
- Files are written whole or not at all, never through a link (femcrowd/files.py); on --resume the links
  planted at the names of the run's files are removed (their targets untouched), as a new run removes the
  files of the run before it.
"""

import fcntl
import os
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError
from ..files import writing

LOCK = ".femcrowd-lock"


class RunLock:
    """A run's hold on its output directory (see the module): acquire() before anything in it changes,
    settled() once it is cleared or rewound, release() when the run is over."""

    def __init__(self, directory):
        self.directory = Path(directory)
        self._file = self._dir = None

    def acquire(self) -> "RunLock":
        """Take the directory, or raise InputError (one line) if another run or a plot holds it."""
        path = self.directory / LOCK
        with writing(path):
            self._file = os.open(path, os.O_RDONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666)
        try:
            if not _flock(self._file, fcntl.LOCK_EX):
                raise InputError(self.directory, None, None, "another femcrowd run is writing into this directory: "
                                 "wait for it to end, or choose another --out")
            self._dir = os.open(self.directory, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            if not _flock(self._dir, fcntl.LOCK_EX):
                raise InputError(self.directory, None, None, "femcrowd plot is reading this directory: run again "
                                 "when it has finished, or choose another --out")
        except BaseException:
            self.release()
            raise
        return self

    def settled(self) -> None:
        """The directory is cleared or rewound: readers (femcrowd plot) may come in."""
        if self._dir is not None:
            os.close(self._dir)
            self._dir = None

    def release(self) -> None:
        self.settled()
        if self._file is not None:
            os.close(self._file)
            self._file = None

    __del__ = release   # a lock dropped unreleased (an exception between open and close) is not kept


def _flock(fd, kind) -> bool:
    """Lock without waiting: False if someone else holds it."""
    try:
        fcntl.flock(fd, kind | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


@contextmanager
def reading(directory):
    """A reader's hold on a run directory (``femcrowd plot``): shared with other readers and with a run in
    progress; refused with one line in the moment a new run clears the directory. Nothing to hold when the
    directory cannot be opened (the reader says what is wrong)."""
    try:
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError:
        fd = None
    try:
        if fd is not None and not _flock(fd, fcntl.LOCK_SH):
            raise InputError(directory, None, None, "a femcrowd run is clearing this directory to start: "
                             "plot it in a moment")
        yield
    finally:
        if fd is not None:
            os.close(fd)

