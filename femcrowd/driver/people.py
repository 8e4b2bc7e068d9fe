"""The people of a case at t = 0 (``femcrowd info``), counted as the first row of its history.csv counts them:
macro, the mass (the integral of the initial density, in the case's density unit: rho_max x the fraction of
saturation); micro, the discs (sampled from the initial density, or read from [micro].positions)."""

from ..case import Case
from ..case.units import people_unit
from .macro_model import MacroModel
from .micro_model import MicroModel
from .scene import build_scene


def initial_people(case: Case) -> dict:
    """{"total": people, "populations": {name: people} (several populations only), "unit": "people" or
    "m^2 at rho_max" (a macro case whose densities are fractions of saturation, case/units.py)}."""
    micro = case["model"]["type"] == "micro"
    model = (MicroModel if micro else MacroModel)(build_scene(case))
    row, column = model.row(), "count" if micro else "mass"
    names = model.names if micro else model.state.populations
    number = int if micro else float
    return {"total": number(row[column]),
            "populations": {name: number(row[f"{column}_{name}"]) for name in names} if len(names) > 1 else {},
            "unit": people_unit(case.config)}
