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

#: the names of the API and the module each comes from, imported at first use (PEP 562): `import femcrowd.case`
#: then loads the case layer alone, not the models
API = {"load_case": "case", "Result": "driver", "Simulation": "driver", "run": "driver"}

__all__ = ["Result", "Simulation", "__version__", "load_case", "run"]


def __getattr__(name):
    if name in API:
        import importlib

        return getattr(importlib.import_module(f".{API[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
