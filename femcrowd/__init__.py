"""femcrowd: finite-element crowd motion with hard congestion.

The Python API (README, "Python API")::

    import femcrowd
    case = femcrowd.load_case("cases/room", ["time.end=5"])
    result = femcrowd.Simulation(case).run()       # nothing written; result.history, result.state
    femcrowd.run(case, out="results/room")        # the files of `femcrowd run`
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("femcrowd")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from .case import load_case  # noqa: E402
from .driver import Result, Simulation, run  # noqa: E402

__all__ = ["Result", "Simulation", "__version__", "load_case", "run"]
