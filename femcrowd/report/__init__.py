"""``femcrowd report OUTDIR``: one self-contained HTML page (figures embedded, no outside file) of a run or of a
study that an engineer can hand in (docs/tools.md, "Report")."""

from .page import report

__all__ = ["report"]
