"""The reference of the case keys (docs/case-format.md), made from the SCHEMA: one table per section.

``python -m femcrowd.case.reference`` prints it; a test checks that the page holds exactly this text.
"""

from .loading import toml_value
from .schema import REQUIRED, SCHEMA, Key, NamedTables


def keys_markdown() -> str:
    """Markdown tables of every key: name, default, meaning."""
    lines = ["| key | default | meaning |", "|---|---|---|"]
    for section, spec in SCHEMA.items():
        rows = spec.items() if isinstance(spec, dict) else [(None, spec)]
        if isinstance(spec, NamedTables):  # the section itself, then the keys of each of its tables
            rows = [(None, spec), *((f"<name>.{name}", key) for name, key in spec.keys.items())]
        for name, key in rows:
            dotted = section if name is None else f"{section}.{name}"
            lines.append(_row(dotted, key))
            array = key.items if isinstance(key, Key) and key.items else {}   # the keys of an array of tables
            for item, sub in array.items():
                lines.append(_row(f"{dotted}[].{item}", sub))
    return "\n".join(lines) + "\n"


def _row(dotted, key) -> str:
    default = "required" if key.default is REQUIRED else "not set" if key.default is None \
        else f"`{toml_value(key.default)}`"
    return f"| `{dotted}` | {default} | {key.doc.replace('|', '&#124;')} |"


if __name__ == "__main__":
    print(keys_markdown(), end="")
