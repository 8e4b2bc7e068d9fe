"""Case directories: ``case.toml`` parsed against a schema with defaults.

Every key of the contract (shared design note "case-format") has a default, so
a small scene needs a small file. Unknown keys, wrong types and bad values
raise :class:`InputError` naming the file, the key and the value. Expressions
are parsed (never evaluated as Python) when the case is loaded. The resolved
configuration (all defaults filled) is echoed into summary.json.
"""

import copy
import difflib
import inspect
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from .errors import InputError
from .exact import SOLUTIONS
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
    "scheme": {"transport": Key("upwind", "choice", ("upwind", "muscl", "compressive"))},
    "exact": {"name": Key(None, "choice", tuple(SOLUTIONS)),
              **{name: Key(None, "number") for name in EXACT_PARAMETERS}},
    "convergence": {"meshes": Key([], "strlist"), "reference": Key(None, "str")},
}


@dataclass
class Case:
    """A loaded case: the resolved configuration and where it came from."""

    config: dict
    file: Path

    @property
    def directory(self):
        return self.file.parent

    def __getitem__(self, section):
        return self.config[section]

    def path(self, relative):
        """A path from the case file, resolved against the case directory."""
        return (self.directory / relative).resolve()

    def expression(self, section, key):
        """The parsed Expression of a number-or-expression key."""
        return Expression(self.config[section][key])


def load_case(case_dir, overrides=()):
    """Load CASE_DIR/case.toml (or a .toml file), apply ``--set key=value`` overrides, validate."""
    path = Path(case_dir)
    file = path / "case.toml" if path.is_dir() else path
    if not file.is_file():
        raise InputError(file, None, None, "case file not found")
    try:
        raw = tomllib.loads(file.read_text())
    except tomllib.TOMLDecodeError as err:
        raise InputError(file, None, None, f"TOML syntax error: {err}") from None
    except UnicodeDecodeError:
        raise InputError(file, None, None, "not a text file") from None
    for item in overrides:
        _apply_override(raw, item, file)
    return Case(_resolve(raw, SCHEMA, file, ""), file.resolve())


def parse_override(item, file="--set"):
    """'a.b=value' -> (['a', 'b'], value); the value is read as TOML, else as a string."""
    if "=" not in item:
        raise InputError(file, item, None, "expected --set section.key=value")
    key, text = item.split("=", 1)
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    return key.strip().split("."), value


def _apply_override(raw, item, file):
    keys, value = parse_override(item, file)
    table = raw
    for k in keys[:-1]:
        table = table.setdefault(k, {})
        if not isinstance(table, dict):
            raise InputError(file, ".".join(keys), value, f"{k!r} is not a table")
    table[keys[-1]] = value


def _resolve(raw, schema, file, prefix):
    """Fill defaults and check every key of one table against the schema."""
    if not isinstance(raw, dict):
        raise InputError(file, prefix.rstrip("."), raw, "expected a table")
    for name in raw:
        if name not in schema:
            close = difflib.get_close_matches(name, list(schema), n=1)
            hint = f" (did you mean {prefix + close[0]!r}?)" if close else ""
            raise InputError(file, prefix + name, raw[name], f"unknown key{hint}")
    out = {}
    for name, spec in schema.items():
        key = prefix + name
        if isinstance(spec, dict):
            out[name] = _resolve(raw.get(name, {}), spec, file, key + ".")
        elif name in raw:
            out[name] = _check(spec, raw[name], file, key)
        elif spec.default is REQUIRED:
            raise InputError(file, key, None, "missing required key")
        else:
            out[name] = copy.deepcopy(spec.default)
    return out


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check(spec, value, file, key):
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
        if not _is_number(value) or (kind == "int" and not isinstance(value, int)):
            fail("expected an integer" if kind == "int" else "expected a number")
        if not math.isfinite(value):
            fail("expected a finite number")
        below = value <= spec.low if spec.low_open else value < spec.low
        if below or value > spec.high:
            lo = "(" if spec.low_open else "["
            fail(f"must be in {lo}{spec.low:g}, {spec.high:g}]")
        return value
    if kind == "expr":
        if _is_number(value):
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
        if not isinstance(value, dict) or not all(_is_number(v) for v in value.values()):
            fail("expected a table of surface-group names to densities")
        return value
    if kind == "radius":
        ok = _is_number(value) and value > 0 or (
            isinstance(value, list) and len(value) == 2 and all(_is_number(v) for v in value)
            and 0 < value[0] <= value[1])
        if not ok:
            fail("expected a positive number or [min, max]")
        return value
    raise AssertionError(kind)
