"""Loading a case directory: ``case.toml`` resolved against the schema, ``--set`` overrides, paths.

Unknown keys, wrong types and bad values raise :class:`InputError` naming the
file, the key and the value. Expressions are parsed (never evaluated as
Python) when the case is loaded. The resolved configuration (all defaults
filled) is echoed into summary.json.

Paths are resolved here, in one place: paths in a case file (``mesh.file``,
``output.dir``, ...) are relative to the case file; an output directory given
on the command line (``--out``) is relative to the current directory.
"""

import copy
import difflib
import json
import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError, not_a_file
from .schema import REQUIRED, SCHEMA, NamedTables, check_value

#: the message of arrays or tables nested deeper than the TOML parser's recursion allows
TOO_DEEP = "arrays or tables nested too deeply (a few hundred levels; a case needs at most three)"
#: the name of a table of a table of tables ([populations.<name>]): it names columns and arrays
TABLE_NAME = re.compile(r"[A-Za-z0-9_-]+")


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

    def path(self, relative) -> Path:
        """A path from the case file, resolved against the case directory."""
        return (self.directory / relative).resolve()

    def output_dir(self, out=None, subdirectory: str = "") -> Path:
        """Where a run writes: ``out`` from the command line (relative to the current directory), else
        ``output.dir`` of the case (relative to the case file) with `subdirectory` appended."""
        if out is not None:
            return Path(out).resolve()
        return self.path(self.config["output"]["dir"]) / subdirectory

    def resolved_toml(self, directory) -> str:
        """This case as TOML, as it runs: defaults filled, overrides applied, the paths it names (mesh.file,
        micro.positions, convergence.meshes and .reference) relative to `directory`: a file there that runs the
        same case on its own."""
        config = copy.deepcopy(self.config)
        moved = lambda name: Path(os.path.relpath(self.path(name), Path(directory).resolve())).as_posix()  # noqa: E731
        config["mesh"]["file"] = moved(config["mesh"]["file"])
        if config["micro"]["positions"] is not None:
            config["micro"]["positions"] = moved(config["micro"]["positions"])
        convergence = config["convergence"]
        convergence["meshes"] = [moved(name) for name in convergence["meshes"]]
        if convergence["reference"] is not None:
            convergence["reference"] = moved(convergence["reference"])
        head = [f"# {self.file.name} of {self.directory} as this run used it: defaults filled, --set applied, paths",
                "# from this directory. `femcrowd run` on this directory runs it again.\n"]
        top = [f"{toml_key(k)} = {toml_value(v)}" for k, v in config.items()
               if not isinstance(v, dict) and v is not None]
        tables = [f"\n[{toml_key(k)}]\n" + "".join(f"{toml_key(key)} = {toml_value(value)}\n"
                                                    for key, value in v.items() if value is not None)
                  for k, v in config.items() if isinstance(v, dict)]
        return "\n".join(head + top) + "\n" + "".join(tables)


def load_case(case_dir, overrides=()) -> Case:
    """Load CASE_DIR/case.toml (or a .toml file), apply overrides, validate.

    overrides: ``--set`` strings ``["time.end=5", ...]`` (values read as TOML), or a mapping
    ``{"time.end": 5, ...}`` of dotted keys to values.
    """
    path = Path(case_dir)
    file = path / "case.toml" if path.is_dir() else path
    if not file.is_file():
        raise InputError(file, None, None, not_a_file(file, "case file"))
    try:
        raw = tomllib.loads(file.read_text(encoding="utf-8-sig"))   # TOML is UTF-8; a byte-order mark is skipped
    except tomllib.TOMLDecodeError as err:
        raise InputError(file, None, None, f"TOML syntax error: {err}") from None
    except UnicodeDecodeError:
        raise InputError(file, None, None, "not a text file") from None
    except RecursionError:
        raise InputError(file, None, None, TOO_DEEP) from None
    if isinstance(overrides, Mapping):
        items = [(key.split("."), value) for key, value in overrides.items()]
    else:
        items = [parse_override(item, file) for item in overrides]
    for keys, value in items:
        _apply_override(raw, keys, value, file)
    return case_from_dict(raw, file)


def case_from_dict(raw: dict, file) -> Case:
    """A case given as the tables of a case file (femcrowd.api: a case in memory), checked and its defaults
    filled as a case file's; `file` names it in errors, its directory resolves the relative paths."""
    file = Path(file)
    return Case(_resolve(copy.deepcopy(raw), SCHEMA, file, ""), file.resolve())


def parse_override(item: str, file="--set") -> tuple[list, object]:
    """'a.b=value' -> (['a', 'b'], value); the value is read as TOML, else as a string."""
    if "=" not in item:
        raise InputError(file, item, None, "expected --set section.key=value")
    key, text = item.split("=", 1)
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    except RecursionError:
        raise InputError(file, key.strip(), text, TOO_DEEP) from None
    return key.strip().split("."), value


def _apply_override(raw, keys, value, file):
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
        elif isinstance(spec, NamedTables):   # a table of named tables: each resolved against its keys
            out[name] = _resolve_tables(raw.get(name, {}), spec, file, key)
        elif name in raw and spec.kind == "table_array":   # an array of tables: each resolved against its keys
            out[name] = [_resolve(item, spec.items, file, f"{key}[{i}].")
                         for i, item in enumerate(check_value(spec, raw[name], file, key))]
        elif name in raw:
            out[name] = check_value(spec, raw[name], file, key)
        elif spec.default is REQUIRED:
            raise InputError(file, key, None, "missing required key")
        else:
            out[name] = copy.deepcopy(spec.default)
    return out


def _resolve_tables(raw, spec, file, key):
    """A table of named tables ([populations.<name>]): each resolved against spec.keys."""
    if not isinstance(raw, dict):
        raise InputError(file, key, raw, f"expected tables [{key}.<name>]")
    for label in raw:
        if not TABLE_NAME.fullmatch(label):
            raise InputError(file, f"{key}.{label}", raw[label], "a name is letters, digits, _ and - only")
    return {label: _resolve(table, spec.keys, file, f"{key}.{label}.") for label, table in raw.items()}


def toml_key(key: str) -> str:
    return key if key and all(c.isalnum() or c in "_-" for c in key) else json.dumps(key)


def toml_value(value) -> str:
    """A value of a resolved case as TOML (written by hand: tomllib only reads, and the values are a few plain
    kinds): tables inline, None entries left out, floats exact (repr), inf and nan as TOML spells them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items() if v is not None) + "}"
    raise TypeError(f"no TOML for {value!r}")
