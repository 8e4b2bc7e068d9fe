"""The cases and meshes that ship with femcrowd (the repository's ``cases/`` and ``meshes/``): in a source
checkout ``femcrowd/shipped/cases`` and ``femcrowd/shipped/meshes`` are links to them, in an installed wheel
copies of them, side by side, so that the relative mesh paths of the cases hold either way. The studies
(``femcrowd stress``, ``femcrowd rimea``, the extensions' refinement studies) find their scenes here."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent


def cases(*parts) -> Path:
    """A directory of the shipped cases, e.g. cases("stress") or cases("rimea", "test01-corridor")."""
    return ROOT.joinpath("cases", *parts)
