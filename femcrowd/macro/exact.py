"""Exact solutions of the macro model (docs/model.md, "Exact solutions"; rho_max = 1, unit speed unless stated).

Each solution gives density(x, y, t) and pressure(x, y, t) as arrays, and the
scalar quantities a study compares (front position, saturated radius,
evacuated mass). They are selected by name in a case's ``[exact]`` table.
"""

import numpy as np


class WallAccumulation:
    """Sol. 1: channel, U = (-1, 0), wall at x = 0, rho0 = a on (x1, x2).

    For t >= x1: saturated zone [0, s(t)], s = a (t - x1) / (1 - a), p = (s - x)^+,
    rho = a on (max(s, x1 - t), x2 - t), valid while s(t) <= x2 - t.
    """

    def __init__(self, a=0.5, x1=0.5, x2=2.5):
        self.a, self.x1, self.x2 = a, x1, x2

    def front(self, t):
        return max(self.a * (t - self.x1) / (1 - self.a), 0.0)

    def density(self, x, y, t):
        s = self.front(t)
        crowd = (x > max(s, self.x1 - t)) & (x < self.x2 - t)
        return np.where(x < s, 1.0, np.where(crowd, self.a, 0.0))

    def pressure(self, x, y, t):
        return np.maximum(self.front(t) - x, 0.0)


class RadialConcentration:
    """Sol. 2: U = -x/|x|, rho0 = a on r < R0. While R(t) + t <= R0:
    rho = 1 on r < R(t) = sqrt(a) t / (1 - sqrt(a)), rho = a (r + t) / r on R < r < R0 - t,
    p = (R^2 - r^2)/ (2 R) ... see pressure()."""

    def __init__(self, a=0.25, R0=0.9):
        self.a, self.R0 = a, R0

    def front(self, t):
        sa = np.sqrt(self.a)
        return sa * t / (1 - sa)

    def density(self, x, y, t):
        r = np.hypot(x, y)
        R = self.front(t)
        with np.errstate(divide="ignore", invalid="ignore"):
            moving = self.a * (r + t) / r
        return np.where(r < R, 1.0, np.where(r < self.R0 - t, moving, 0.0))

    def pressure(self, x, y, t):
        """p = (R(t) - r)^+."""
        return np.maximum(self.front(t) - np.hypot(x, y), 0.0)


class SaturatedEvacuation:
    """Sol. 3: channel [0, L] x [0, 1], exit at x = 0, U = (-(1 + k x), 0), rho0 = 1 on x < s0.

    s(t) = (s0 + 2/k) exp(-k t/2) - 2/k, p = k x (s - x) / 2 on x < s, evacuated = s0 - s(t)
    (per unit channel width).
    """

    def __init__(self, k=1.0, s0=1.0):
        self.k, self.s0 = k, s0

    def front(self, t):
        k = self.k
        return max((self.s0 + 2 / k) * np.exp(-k * t / 2) - 2 / k, 0.0)

    def evacuated(self, t):
        return self.s0 - self.front(t)

    def density(self, x, y, t):
        return np.where(x < self.front(t), 1.0, 0.0)

    def pressure(self, x, y, t):
        s = self.front(t)
        return np.where(x < s, self.k * x * (s - x) / 2, 0.0)


class DiscProjection:
    """Sol. 4: one correction step of rho~ = c on r < R (c > 1), zero elsewhere.

    rho = 1 on r < R' = R sqrt(c); phi = (c R^2/4) ln c - (c - 1) r^2/4 on r < R,
    phi = (r^2 - R'^2)/4 - (R'^2/2) ln(r/R') on R < r < R', 0 beyond.
    """

    def __init__(self, c=2.0, R=0.4):
        self.c, self.R = c, R
        self.R1 = R * np.sqrt(c)

    def initial(self, x, y, t=0.0):
        return np.where(np.hypot(x, y) < self.R, self.c, 0.0)

    def density(self, x, y, t=0.0):
        return np.where(np.hypot(x, y) < self.R1, 1.0, 0.0)

    def phi(self, x, y):
        r = np.hypot(x, y)
        c, R, R1 = self.c, self.R, self.R1
        with np.errstate(divide="ignore"):
            outer = (r ** 2 - R1 ** 2) / 4 - (R1 ** 2 / 2) * np.log(r / R1)
        inner = c * R ** 2 / 4 * np.log(c) - (c - 1) * r ** 2 / 4
        return np.where(r < R, inner, np.where(r < R1, outer, 0.0))


SOLUTIONS = {"wall-accumulation": WallAccumulation, "radial": RadialConcentration,
             "saturated-evacuation": SaturatedEvacuation, "disc-projection": DiscProjection}
