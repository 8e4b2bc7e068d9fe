"""The desired speed on a stair (docs/floors.md, "Stair speeds"): published speeds up and down a stair, by name, and
the speed of each cell of a stair with up and down speeds, chosen by the direction people walk there.

A stair of ``velocity.speeds`` given as ``{ up = ..., down = ... }`` has two speeds; the direction of each cell is
that of its desired velocity U: up where U climbs the cell's plane (s . U > 0, s = grad z its slope), down
elsewhere. U points down the walking distance d, so the direction follows the route (the exit people head for),
and under the route choice it follows the route of each re-solve.
"""

import numpy as np

#: published desired speeds on stairs (m/s), by the name a case gives them (velocity.speeds); each quoted as its
#: source states it, along the line of walking (docs/floors.md, "Stair speeds", says where; femcrowd/studies/
#: experiments.csv, kind "stair", has the rows): the upward speeds of four handbooks as Burghardt, Seyfried and
#: Klingsch (2014, Table 1) compare them, the free speeds (projected density D <= 0.05) up and down a stair of
#: Predtechenskii and Milinskii's tables (GOST 12.1.004-91, appendix 2), and the speeds JuPedSim sets for RiMEA
#: tests 2 and 3
STAIR_SPEEDS = {
    "fruin-up": 0.55,
    "weidmann-up": 0.61,
    "predtechenskii-up": 0.63,
    "nelson-mowrer-up": 0.80,
    "gost-free-up": 60.0 / 60.0,
    "gost-free-down": 100.0 / 60.0,
    "rimea-up": 0.5,
    "rimea-down": 0.75,
}
#: the directions of a stair's table in velocity.speeds
DIRECTIONS = ("up", "down")


def speed_value(value) -> float:
    """A speed of velocity.speeds: a number (m/s) or the name of one of STAIR_SPEEDS."""
    return STAIR_SPEEDS[value] if isinstance(value, str) else float(value)


class Climbs:
    """The cells of the stairs with up and down speeds and those speeds (one value per cell)."""

    def __init__(self, cells: np.ndarray, up: np.ndarray, down: np.ndarray):
        self.cells, self.up, self.down = cells, up, down

    def speed(self, base: np.ndarray, slope: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """The desired speed per cell: `base` off these stairs; on them `up` where the plan vector `velocity` (the
        direction of U) climbs the cell's plane, s . U > 0, `down` elsewhere."""
        speed = base.copy()
        rising = np.einsum("ij,ij->i", slope[self.cells], velocity[self.cells]) > 0
        speed[self.cells] = np.where(rising, self.up, self.down)
        return speed
