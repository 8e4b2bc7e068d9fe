"""What the models offer a case file: the names of the transports, the speed laws, the disc strategies, the
exact solutions (with their parameters) and the published stair speeds, and the check of a speed law. The case
layer (case/schema.py) asks here; a model is imported at the first question about it, so that ``import
femcrowd.case`` needs none of them, and the lists live where the models define them (``TRANSPORTS``, ``NAMES``,
``STRATEGIES``, ``SOLUTIONS``, ``STAIR_SPEEDS``)."""

import importlib
import inspect
from functools import cache


@cache
def transports() -> tuple:
    """The names of ``[scheme] transport`` (macro/transport)."""
    return tuple(importlib.import_module("femcrowd.macro.transport").TRANSPORTS)


@cache
def speed_laws() -> tuple:
    """The named laws of ``[velocity] speed_law`` (macro/speed_law.py); any other value is an expression in rho."""
    return tuple(importlib.import_module("femcrowd.macro.speed_law").NAMES)


@cache
def stair_speeds() -> tuple:
    """The names of the published stair speeds of ``[velocity] speeds`` (macro/stairs.py)."""
    return tuple(importlib.import_module("femcrowd.macro.stairs").STAIR_SPEEDS)


def speed_law_error(spec: str):
    """Why `spec` is not a speed law (one line), or None."""
    module = importlib.import_module("femcrowd.macro.speed_law")
    try:
        module.SpeedLaw(spec)
    except module.LawError as err:
        return str(err)
    return None


@cache
def strategies() -> tuple:
    """The names of ``[micro] strategy`` (micro/strategies.py)."""
    return tuple(importlib.import_module("femcrowd.micro.strategies").STRATEGIES)


@cache
def exact_solutions() -> dict:
    """{name: its parameters} of the exact solutions of ``[exact]`` (macro/exact.py)."""
    solutions = importlib.import_module("femcrowd.macro.exact").SOLUTIONS
    return {name: tuple(inspect.signature(cls).parameters) for name, cls in solutions.items()}
