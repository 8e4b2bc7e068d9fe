"""Command line: ``femcrowd run CASE`` and the other commands (click)."""

from . import run_commands, study_commands, tool_commands  # noqa: F401  (they register the commands)
from .main import main

__all__ = ["main"]
