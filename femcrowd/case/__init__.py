"""Case directories: the schema of case.toml (keys, defaults, checks), loading with overrides and paths,
safe expressions, and the commented template of ``femcrowd new``."""

from ..expressions import Expression, ExpressionError
from .loading import Case, load_case, parse_override
from .schema import SCHEMA

__all__ = ["SCHEMA", "Case", "Expression", "ExpressionError", "load_case", "parse_override"]
