"""The report's page: the values of a run (report/run.py) or a study (report/study.py) in the template
page.html, rendered by Jinja2 with HTML escaping (every value of a case file is escaped)."""

import math
from pathlib import Path

from .. import __version__
from ..driver.ownership import reading
from ..driver.reading import RunDirectory
from ..errors import InputError
from ..files import write_text
from .numbers import MEAN_SHARE, PEAK_BIN, QUEUE_DENSITY
from .run import run_context
from .study import is_study, study_context

DOOR_NOTE = (f"Through: people who passed the door. Mean flow: from the first to the last {100 * MEAN_SHARE:g} % of "
             f"them. Peak flow: the largest mean over bins of {PEAK_BIN:g} s. Time at capacity: the seconds the flow "
             f"was the capacity x width. Longest queue: the most people in the cells at {QUEUE_DENSITY:g} x rho_max "
             "or more connected to the door, over the frames (macro). Counting lines ([[measure.lines]]): their net "
             "count, left to right. -: not measured (no capacity; micro runs record no flow per door: draw counting "
             "lines).")


def number(value) -> str:
    """A value of the page: 4 significant digits, '-' for none or nan."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.4g}" if isinstance(value, float | int) and not isinstance(value, bool) else str(value)


def seconds(value) -> str:
    """A time of the page: '12.5 s', or '-' for none or nan."""
    text = number(value)
    return text if text == "-" else f"{text} s"


def render(context: dict) -> str:
    import jinja2

    env = jinja2.Environment(loader=jinja2.PackageLoader("femcrowd.report", "."), autoescape=True,
                             undefined=jinja2.StrictUndefined)
    env.filters["num"], env.filters["seconds"] = number, seconds
    return env.get_template("page.html").render(generator=__version__, door_note=DOOR_NOTE, **context)


def report(directory, times=None, out=None) -> Path:
    """Write the report of the run or study in `directory` to `out` (default: directory/report.html); the
    times of the maps (default: a few until 95 % are out). Returns the page's path."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(directory, None, None, "not a directory (give the output directory of a run or a study)")
    with reading(directory):
        if is_study(directory):
            context = {"title": directory.name, "directory": str(directory), "run": None,
                       "study": study_context(directory)}
        else:
            run = RunDirectory(directory)
            context = {"title": run.title, "directory": str(directory), "run": run_context(run, times), "study": None}
        path = Path(out) if out is not None else directory / "report.html"
        write_text(path, render(context))
    return path
