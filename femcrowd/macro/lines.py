"""The mass a step moves across measurement lines (docs/scenes.md, "Measurement lines"): the transport's facet
fluxes of the coming prediction (capped at the doors) plus the correction's T_e (phi_K - phi_L - j_e), on the
facets of each line, signed so that they count from the left of the line to its right."""

import numpy as np


class LineFlux:
    """The facets of the lines (``owner``: the line of each, ``sign``: +1 where f2t[0] is on the line's left):
    before_step() takes the prediction's fluxes, after_step() adds the correction's and gives the mass that
    crossed each line in the step (units of rho_max x m^2)."""

    def __init__(self, domain, facets, sign, owner, lines: int):
        self.domain, self.facets, self.sign, self.owner, self.lines = domain, facets, sign, owner, lines
        self._doors, self._moved = None, None

    def before_step(self, solver, state, dt: float) -> None:
        """The prediction's fluxes on the lines' facets (a hook after the sources)."""
        self._doors = solver.boundary.at(state.t)
        self._moved = solver.facet_flux(state, dt, self.facets)

    def after_step(self, result) -> np.ndarray:
        """The mass that crossed each line in the step just made."""
        moved = self._moved + result.flux.facet_flux(self.domain, self._doors, self.facets)
        return np.bincount(self.owner, self.sign * moved, self.lines)
