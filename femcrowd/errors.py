"""The error type for bad user input (case files, meshes, geometry files), the interruption of a
command that kept part of its work, and a study that kept its finished runs when others failed.

The CLI prints each as a single line and exits non-zero (2, 130, 1), without a traceback.
"""


#: the most characters of a value that a message shows (a 200,000-term expression is not echoed whole)
SHOWN = 200


class InputError(Exception):
    """Bad user input: names the file, the key and the offending value (its start, if it is long)."""

    def __init__(self, file, key, value, message):
        self.file, self.key, self.value, self.message = str(file), key, value, message
        shown = repr(value)
        if len(shown) > SHOWN:
            shown = f"{shown[:SHOWN]}... ({len(str(value))} characters)"
        where = self.file if key is None else f"{self.file}: {key} = {shown}"
        super().__init__(f"{where}: {message}")


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT, SIGTERM, SIGHUP) during a command that saved part of its work: the message says what
    is kept and where."""


class StudyFailed(Exception):
    """A study some of whose runs failed: the finished ones are tabulated (``report``: the study's text); the
    message says how many failed, the first one's reason, and where the table is."""

    def __init__(self, message: str, report: str = ""):
        super().__init__(message)
        self.report = report
