"""Property-based tests (hypothesis) of what reads user input: random valid and invalid case files, --set
overrides and expressions give a loaded case (a value) or one line of InputError, never another exception.

The examples are derandomized (the same ones every run, no example database written; hypothesis's caches go
under pytest's temporary directory, tests/conftest.py) and few, so that the default tier stays fast and does
not depend on a draw.
"""

import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from femcrowd.case import load_case
from femcrowd.case.loading import toml_key, toml_value
from femcrowd.case.schema import SCHEMA, Key, NamedTables
from femcrowd.errors import InputError
from femcrowd.expressions import FUNCTIONS, Expression

QUICK = settings(max_examples=100, deadline=None, derandomize=True, database=None,
                 suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
X = np.linspace(-2.0, 2.0, 7)

# --- expressions ----------------------------------------------------------------------------------------------

NAMES = ["x", "y", "t", "pi", "e", "inf", "rho", "z", "__import__", "os", "True", "None"]
ODD = ["1e400", "10**400", "1" * 5000, "''", "'a'", "1j", "[1]", "x.real", "x[0]", "(lambda: 1)()", "{}", "...",
       "\x00", "\\", "#", "((", ")", "x if", "import os", "f'{x}'", "x := 1", "*x", "await x", "yield"]
BINARY = ["+", "-", "*", "/", "**", "%", "//", "&", "|", "^", "<<", "@", "<", "<=", ">", ">=", "==", "!=", " and ",
          " or ", " in ", " is "]
CALLED = sorted(FUNCTIONS) + ["eval", "open", "getattr", "print"]

numbers = st.one_of(st.integers(-10 ** 6, 10 ** 6).map(str),
                    st.floats(allow_nan=False, allow_infinity=False).map(repr))
leaves = st.one_of(st.sampled_from(NAMES), numbers, st.sampled_from(ODD))


def _combine(parts):
    return st.one_of(
        st.tuples(parts, st.sampled_from(BINARY), parts).map(lambda p: f"({p[0]}{p[1]}{p[2]})"),
        st.tuples(st.sampled_from(["-", "+", "not ", "~"]), parts).map("".join),
        st.tuples(st.sampled_from(CALLED), st.lists(parts, max_size=4)).map(lambda p: f"{p[0]}({', '.join(p[1])})"),
        st.tuples(parts, parts, parts).map(lambda p: f"({p[0]} if {p[1]} else {p[2]})"),
        st.tuples(parts, st.sampled_from(["<", "<="]), parts, st.sampled_from([">", "=="]), parts).map("".join))


expressions = st.one_of(st.recursive(leaves, _combine, max_leaves=12), st.text(max_size=40),
                        st.integers(1, 400).map(lambda n: "(" * n + "x" + ")" * n),
                        st.integers(1, 300).map(lambda n: "-" * n + "x"))


@QUICK
@given(source=expressions, t=st.floats(-1e3, 1e3))
def test_an_expression_is_a_finite_value_or_one_line(source, t):
    """Parsed and evaluated on arrays: a finite array of their shape, or InputError naming the key (the
    whitelist, the limits on size and depth, a value that is not finite), whatever the text."""
    try:
        value = Expression(source, origin=("case.toml", "initial.density"))(X, X[::-1], t)
    except InputError as err:
        assert err.key == "initial.density" and "\n" not in str(err)
        return
    assert value.shape == X.shape and np.all(np.isfinite(value))


# --- case files -----------------------------------------------------------------------------------------------

#: TOML values of every kind, nested a little (tables with odd keys, arrays of mixed kinds)
scalars = st.one_of(st.booleans(), st.integers(-2 ** 63, 2 ** 63 - 1), st.floats(), st.text(max_size=12),
                    st.sampled_from(["0.5 * (x < 4)", "x +", "1e999", "__import__('os')", "exit", "upwind", "micro",
                                     "weidmann", "congestion", "field"]))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                      max_leaves=8)


def _keys(schema, prefix=""):
    """The dotted keys of the schema, tables of named tables as one example name."""
    for name, spec in schema.items():
        if isinstance(spec, dict):
            yield from _keys(spec, f"{prefix}{name}.")
        elif isinstance(spec, NamedTables):
            yield from _keys(spec.keys, f"{prefix}{name}.crowd.")
        elif isinstance(spec, Key):
            yield f"{prefix}{name}"


KEYS = sorted(_keys(SCHEMA))
#: a value the schema accepts for each kind of key (choices: the first), so that drawn cases get past the first key
GOOD = {"str": "a", "bool": True, "number": 1.0, "int": 1, "expr": "0.5 * x", "strlist": ["exit"],
        "fields": ["density"], "regions": {"crowd": 0.5}, "speeds": {"stair": {"up": "weidmann-up", "down": 0.7}},
        "law": "linear", "exact": {},
        "radius": 0.2, "name": "a", "point": [0.0, 1.0], "polygon": [[0, 0], [1, 0], [0, 1]], "capacities": {"a": 1.0},
        "schedules": {"exit": [[0, 1]]}, "table_array": []}


def _spec(dotted):
    spec = SCHEMA
    for part in dotted.split("."):
        spec = spec.keys if isinstance(spec, NamedTables) else spec
        spec = spec[part] if part in spec else spec
    return spec


def _good(dotted):
    spec = _spec(dotted)
    if spec.kind == "choice":
        choices = spec.choices() if callable(spec.choices) else spec.choices
        return choices[0]
    if spec.kind in ("number", "int"):
        low = spec.low if math.isfinite(spec.low) else 0
        return (type(GOOD[spec.kind]))(min(max(low + 1, 1), spec.high)) if spec.high > low else low
    return GOOD[spec.kind]


entries = st.dictionaries(st.one_of(st.sampled_from(KEYS), st.text(min_size=1, max_size=10)),
                          st.one_of(st.sampled_from([None]), values), max_size=8)


def _nest(flat) -> dict:
    """{"a.b": v} -> {"a": {"b": v}}; None: the good value of a schema key (an unknown key: skipped)."""
    out = {"mesh": {"file": "mesh.msh"}}
    for dotted, value in flat.items():
        if value is None:
            if dotted not in KEYS:
                continue
            value = _good(dotted)
        *tables, last = dotted.split(".")
        table = out
        for name in tables:
            table = table.setdefault(name, {}) if isinstance(table.get(name, {}), dict) else {}
        table[last] = value
    return out


def _toml(config: dict) -> str:
    top = [f"{toml_key(k)} = {toml_value(v)}" for k, v in config.items() if not isinstance(v, dict)]
    tables = [f"[{toml_key(k)}]\n" + "".join(f"{toml_key(key)} = {toml_value(value)}\n" for key, value in v.items())
              for k, v in config.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n" + "\n".join(tables)


def _loads_or_one_line(path, overrides=()):
    try:
        case = load_case(path, overrides)
    except InputError as err:
        assert "\n" not in str(err), str(err)
        return None
    assert isinstance(case.config["mesh"]["file"], str) and set(case.config) == set(SCHEMA)
    return case


@QUICK
@given(flat=entries)
@example(flat={"time.end\nx": 1})   # a key with a line break: shown quoted, on one line
def test_a_case_file_loads_or_is_one_line(tmp_path, flat):
    """A case.toml of schema keys and others, with good values and values of any kind: a Case with every
    section, or InputError in one line."""
    (tmp_path / "case.toml").write_text(_toml(_nest(flat)))
    _loads_or_one_line(tmp_path)


@QUICK
@given(text=st.one_of(st.text(max_size=200), st.binary(max_size=200).map(lambda b: b.decode("latin-1")),
                      st.integers(1, 2000).map(lambda n: "[mesh]\nfile = " + "[" * n + "]" * n),
                      st.integers(1, 2000).map(lambda n: "a = " + "{b = " * n + "1" + "}" * n)),
       bom=st.booleans())
def test_any_text_loads_or_is_one_line(tmp_path, text, bom):
    """Text that is mostly not TOML (or TOML nested hundreds of levels deep), with or without a byte-order
    mark, and bytes that are not UTF-8."""
    (tmp_path / "case.toml").write_bytes(b"\xef\xbb\xbf" * bom + text.encode("utf-8", "surrogatepass"))
    _loads_or_one_line(tmp_path)


@QUICK
@given(overrides=st.lists(st.one_of(st.tuples(st.sampled_from(KEYS), st.text(max_size=30)).map("=".join),
                                    st.text(max_size=30),
                                    st.integers(1, 2000).map(lambda n: "time.end=" + "[" * n + "]" * n)),
                          max_size=4))
@example(overrides=["time.end\n"])   # no "=": the key shown quoted, on one line
def test_set_overrides_load_or_are_one_line(tmp_path, overrides):
    """--set strings of any text on a good case: the case, or InputError in one line."""
    (tmp_path / "case.toml").write_text('[mesh]\nfile = "mesh.msh"\n')
    _loads_or_one_line(tmp_path, overrides)
