"""The state of the macro model (PyClaw's State): the unknowns at time t, one array with a population axis."""

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MacroState:
    """rho: (populations, cells) densities in units of rho_max (one population: shape (1, cells));
    p: (cells,) the pressure of the last step; evacuated: (populations, exits) the mass that left
    through each exit so far (exits in the order of the case's boundary.exits); t; steps taken;
    jump: (facets,) the pressure jump across the capped door facets in the last step (None in a scene
    without door capacities)."""

    rho: np.ndarray
    p: np.ndarray
    evacuated: np.ndarray
    t: float = 0.0
    steps: int = 0
    populations: tuple = field(default=("crowd",))
    jump: np.ndarray = None

    @classmethod
    def initial(cls, rho0: np.ndarray, exits: int, populations=("crowd",)) -> "MacroState":
        """The state at t = 0 for initial densities rho0 (populations, cells)."""
        rho = np.atleast_2d(np.asarray(rho0, float))
        return cls(rho, np.zeros(rho.shape[1]), np.zeros((len(rho), exits)), populations=tuple(populations))

    @property
    def density(self) -> np.ndarray:
        """The total density, (cells,): what the congestion constraint rho <= 1 applies to."""
        return self.rho[0] if len(self.rho) == 1 else self.rho.sum(axis=0)
