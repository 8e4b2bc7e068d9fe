"""The record of one time step, the same for both models: what a model's step hands to the driver
(``Model.step`` -> ``Model.row``) and to the hooks after the step. Each model adds its own diagnostics
(:class:`femcrowd.macro.solver.MacroStep`, :class:`femcrowd.micro.scheme.StepInfo`)."""

from dataclasses import dataclass


@dataclass
class Step:
    """time: at the end of the step; dt: its length (s); seconds: its wall time; iterations: those of its
    correction, the active-set iterations of the density's projection (Maury, Roudneff-Chupin, Santambrogio
    2010) or the iterations of the discs' projection (Maury, Venel 2011), 0 when none was needed."""

    time: float
    dt: float
    seconds: float
    iterations: int
