"""Running a case: the scene of a case (scene), the two models as the loop sees them (macro_model,
micro_model), the time loop (loop), the record of diagnostics (recorder), writing and reading the
output directory (output, reading), and one run, the Python API (run)."""

from .run import Result, Simulation, run

__all__ = ["Result", "Simulation", "run"]
