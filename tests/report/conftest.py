"""A short run of the shipped bottleneck whose exit works at its capacity, and its report (made once)."""

import pytest
from click.testing import CliRunner

from femcrowd.cli import main

from ..support import CASES


@pytest.fixture(scope="session")
def capped_run(tmp_path_factory):
    """cases/bottleneck for 6 s, the crowd starting before the door, the exit's capacity 1 persons/(m s): it
    reaches it within the run (frames every 2 s)."""
    out = tmp_path_factory.mktemp("bottleneck") / "out"
    result = CliRunner().invoke(main, ["run", str(CASES / "bottleneck"), "--out", str(out), "-q",
                                       "--set", "time.end=6", "--set", "output.every=2",
                                       "--set", 'initial.density="2.5 * (x > 5) * (x < 8)"',
                                       "--set", "boundary.capacity.exit=1.0"])
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture(scope="session")
def report_page(capped_run):
    """The report of the run, by `femcrowd report` (report.html in the run's directory)."""
    result = CliRunner().invoke(main, ["report", str(capped_run), "--times", "0,4"])
    assert result.exit_code == 0, result.output
    return capped_run / "report.html"
