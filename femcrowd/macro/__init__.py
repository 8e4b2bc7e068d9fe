"""The macroscopic model (Maury, Roudneff-Chupin, Santambrogio, Venel 2011): a density rho <= 1 moved by
u = U - grad p. State (state), desired velocities (velocity), prediction (transport/), correction
(projection/), the step that joins them (solver), output velocity (reconstruction), invariants
(diagnostics) and the exact solutions of docs/model.md (exact)."""

from .solver import MacroSolver
from .state import MacroState

__all__ = ["MacroSolver", "MacroState"]
