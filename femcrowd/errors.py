"""The error type for bad user input (case files, meshes, geometry files), the interruption of a
command that kept part of its work, and a study that kept its finished runs when others failed.

The CLI prints each as a single line and exits non-zero (2; a failed run or study 1; 130), without a traceback.
"""

import stat
from pathlib import Path

#: the most characters of a value that a message shows (a 200,000-term expression is not echoed whole)
SHOWN = 200


class InputError(Exception):
    """Bad user input: names the file, the key and the offending value (its start, if it is long)."""

    def __init__(self, file, key, value, message):
        self.file, self.key, self.value, self.message = str(file), key, value, message
        shown = repr(value)
        if len(shown) > SHOWN:
            shown = f"{shown[:SHOWN]}... ({len(str(value))} characters)"
        where = _line(self.file) if key is None else f"{_line(self.file)}: {_line(key)} = {shown}"
        super().__init__(f"{where}: {message}")


def _line(name) -> str:
    """A file or key name as it shows in one line: quoted (repr) when it holds a line break or another
    unprintable character."""
    name = str(name)
    return name if name.isprintable() else repr(name)


class RunFailed(InputError):
    """A run that went wrong on the way (a disc through a wall): one line naming the file and the key most likely
    responsible; the command exits with 1, the files written so far are kept."""


#: what a path that is not a regular file is, by its stat type
KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a fifo (named pipe)"), (stat.S_ISCHR, "a character device"),
         (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def not_a_file(path, what: str) -> str:
    """Why `path` cannot be read as `what` ("mesh file", ...): not found, or not a regular file but a directory,
    a fifo, a device (which would block or never end)."""
    try:
        mode = Path(path).stat().st_mode
    except OSError:
        return f"{what} not found"
    kind = next((f"{name}, not" for test, name in KINDS if test(mode)), "not")
    return f"is {kind} a regular file: expected the {what}"


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT, SIGTERM, SIGHUP) during a command that saved part of its work: the message says what
    is kept and where."""


class StudyFailed(Exception):
    """A study some of whose runs failed: the finished ones are tabulated (``report``: the study's text); the
    message says how many failed, the first one's reason, and where the table is."""

    def __init__(self, message: str, report: str = ""):
        super().__init__(message)
        self.report = report
