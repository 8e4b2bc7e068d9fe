"""The keys of a case file: their defaults and the checks of their values (docs/case-format.md lists them).

Every key has a default, so a small scene needs a small file. A value is checked by its
kind (string, number in a range, choice, expression, ...); a bad one raises
:class:`InputError` naming the file, the key and the value.
"""

import inspect
import math
from dataclasses import dataclass

from ..errors import InputError
from ..macro.exact import SOLUTIONS
from ..macro.transport import TRANSPORTS
from .expressions import Expression, ExpressionError

REQUIRED = object()
FIELDS = ("density", "pressure", "velocity")
#: parameters of the exact solutions (femcrowd.exact), keys of the [exact] table
EXACT_PARAMETERS = sorted({p for cls in SOLUTIONS.values() for p in inspect.signature(cls).parameters})


@dataclass(frozen=True)
class Key:
    """One case key: its default and the check that turns a raw TOML value into a clean one."""

    default: object
    kind: str
    choices: tuple = ()
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False


SCHEMA = {
    "title": Key("", "str"),
    "mesh": {"file": Key(REQUIRED, "str"), "refine": Key(0, "int", low=0, high=8)},
    "boundary": {"exits": Key([], "strlist")},
    "model": {"type": Key("macro", "choice", ("macro", "micro")),
              "rho_max": Key(1.0, "number", low=0, low_open=True)},
    "velocity": {"type": Key("exits", "choice", ("exits", "field")),
                 "speed": Key(1.0, "expr"), "ux": Key(0.0, "expr"), "uy": Key(0.0, "expr")},
    "initial": {"density": Key(0.0, "expr"), "regions": Key({}, "regions")},
    "time": {"end": Key(10.0, "number", low=0, low_open=True),
             "cfl": Key(0.5, "number", low=0, high=1.0, low_open=True),
             "dt": Key(None, "number", low=0, low_open=True),
             "stop_when_empty": Key(True, "bool"),
             "empty_fraction": Key(1e-4, "number", low=0, high=1, low_open=True)},
    "output": {"dir": Key("output", "str"),
               "every": Key(0.5, "number", low=0, low_open=True),
               "fields": Key(list(FIELDS), "fields")},
    "projection": {"direct_max": Key(1_000_000, "int", low=0),
                   "tol": Key(1e-12, "number", low=0, high=1e-6, low_open=True)},
    "micro": {"radius": Key(0.2, "radius"), "count": Key(None, "int", low=1),
              "seed": Key(1, "int"), "positions": Key(None, "str"),
              "method": Key("exact", "choice", ("exact", "uzawa"))},
    "scheme": {"transport": Key("upwind", "choice", tuple(TRANSPORTS))},
    "exact": {"name": Key(None, "choice", tuple(SOLUTIONS)),
              **{name: Key(None, "number") for name in EXACT_PARAMETERS}},
    "convergence": {"meshes": Key([], "strlist"), "reference": Key(None, "str")},
}


def is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_value(spec: Key, value, file, key: str):
    """The clean value of a raw TOML value for the key `key`, or InputError."""
    def fail(message):
        raise InputError(file, key, value, message)

    kind = spec.kind
    if kind == "str":
        if not isinstance(value, str):
            fail("expected a string")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            fail("expected true or false")
        return value
    if kind == "choice":
        if value not in spec.choices:
            fail(f"expected one of {', '.join(map(repr, spec.choices))}")
        return value
    if kind in ("number", "int"):
        if not is_number(value) or (kind == "int" and not isinstance(value, int)):
            fail("expected an integer" if kind == "int" else "expected a number")
        if not math.isfinite(value):
            fail("expected a finite number")
        below = value <= spec.low if spec.low_open else value < spec.low
        if below or value > spec.high:
            lo = "(" if spec.low_open else "["
            fail(f"must be in {lo}{spec.low:g}, {spec.high:g}]")
        return value
    if kind == "expr":
        if is_number(value):
            if not math.isfinite(value):
                fail("expected a finite number")
            return value
        if not isinstance(value, str):
            fail("expected a number or an expression string")
        try:
            Expression(value)
        except ExpressionError as err:
            fail(str(err))
        return value
    if kind in ("strlist", "fields"):
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            fail("expected a list of strings")
        if kind == "fields":
            bad = [v for v in value if v not in FIELDS]
            if bad:
                fail(f"unknown field {bad[0]!r} (fields: {', '.join(FIELDS)})")
        return value
    if kind == "regions":
        if not isinstance(value, dict) or not all(is_number(v) for v in value.values()):
            fail("expected a table of surface-group names to densities")
        return value
    if kind == "radius":
        ok = is_number(value) and value > 0 or (
            isinstance(value, list) and len(value) == 2 and all(is_number(v) for v in value)
            and 0 < value[0] <= value[1])
        if not ok:
            fail("expected a positive number or [min, max]")
        return value
    raise AssertionError(kind)
