"""The correction step of the macro model: the exact projection onto {rho <= 1} (lcp), with its index-set
tools (sets), closed rooms and their gauge (rooms), kept linear solvers (solvers) and warm start."""

from .lcp import PressureFlux, Projection, ProjectionError
from .solvers import CellOrder

__all__ = ["CellOrder", "PressureFlux", "Projection", "ProjectionError"]
