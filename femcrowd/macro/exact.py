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


# --- the extensions (docs/extensions.md): exact solutions that are not [exact] references -----------


def lwr_riemann(left, right, xi):
    """The entropy solution of d_t rho + d_x (rho (1 - rho)) = 0 from (left | right) at x/t = xi: a shock
    of speed 1 - left - right when left < right, else the fan rho = (1 - xi)/2 (Lighthill, Whitham 1955)."""
    if left < right:
        return np.where(xi < 1 - left - right, left, right)
    return np.clip((1 - xi) / 2, right, left)


class LWRRiemann:
    """A Riemann problem of the linear speed law f = 1 - rho, U0 = (1, 0), in the channel [0, length] with a
    wall at x = 0 and an exit at x = length: rho0 = left on x < x0, right on x > x0.

    Three Riemann problems that do not meet before ``valid_until``: the wall (vacuum | left) at 0 (the rear
    leaves at f(left)), (left | right) at x0, and (right | vacuum) at the exit, whose fan enters the channel
    when right > 1/2 (the exit passes at most the capacity max g = 1/4 per unit width).
    """

    def __init__(self, left=0.1, right=0.7, x0=2.0, length=4.0):
        self.left, self.right, self.x0, self.length = left, right, x0, length
        self.cuts = (x0 / 2, (x0 + length) / 2)   # each problem owns the x between the cuts

    def density(self, x, y, t):
        t = max(t, 1e-300)
        x = np.asarray(x, float)
        a, b = self.cuts
        return np.where(x < a, lwr_riemann(0.0, self.left, x / t),
                        np.where(x < b, lwr_riemann(self.left, self.right, (x - self.x0) / t),
                                 lwr_riemann(self.right, 0.0, (x - self.length) / t)))

    @property
    def shock_speed(self):
        return 1 - self.left - self.right

    def valid_until(self):
        """The time until which the three problems' waves stay between the cuts."""
        a, b = self.cuts
        speeds = [1 - self.left - self.right] if self.left < self.right else [1 - 2 * self.left, 1 - 2 * self.right]
        limits = [(b - self.x0) / s if s > 0 else (a - self.x0) / s for s in speeds if s != 0]
        if self.left > 0:
            limits.append(a / (1 - self.left))
        if self.right > 0.5:
            limits.append((self.length - b) / (2 * self.right - 1))
        return min(limits, default=np.inf)


class HeadOnPopulations:
    """Two populations meeting head-on: A = a on (-x2, -x1) with U = (+1, 0), B = a on (x1, x2) with
    U = (-1, 0). The total is solution 1 on each side (a saturated zone |x| < s(t), s = a (t - x1) / (1 - a))
    while the blocks arrive. Inside the zone the total velocity is 0, so grad p = rho_A - rho_B and
    u_A = 2 rho_B, u_B = -2 rho_A: the fraction c of A solves d_t c + d_x (2 c (1 - c)) = 0, a fan from the
    contact line, c = (1 - x / (2 tau))/2 with tau = t - x1, clipped to [1 - c_e, c_e], c_e = a / (2 (1 - a))
    (the state at the zone's edge x = -s that lets the pure A outside in and no B out). The model itself
    mixes the populations there (valid for 1/2 <= a < 2/3, until the blocks have arrived).
    """

    def __init__(self, a=0.6, x1=0.5, x2=1.5):
        if not 0.5 <= a < 2 / 3:
            raise ValueError("the mixing fan holds for 1/2 <= a < 2/3")
        self.a, self.x1, self.x2 = a, x1, x2
        self.total = WallAccumulation(a, x1, x2)
        self.edge = a / (2 * (1 - a))
        self.valid_until = (1 - a) * x2 + a * x1   # the last of each block arrives

    def fraction(self, x, t):
        """c: the share of A in the total at x (1 left of the zone, 0 right of it)."""
        tau = max(t - self.x1, 1e-300)
        s = self.total.front(t)
        fan = np.clip((1 - x / (2 * tau)) / 2, 1 - self.edge, self.edge)
        return np.where(x < -s, 1.0, np.where(x > s, 0.0, fan))

    def density(self, x, y, t):
        return self.total.density(np.abs(x), y, t)

    def density_a(self, x, y, t):
        return self.density(x, y, t) * self.fraction(x, t)

    def density_b(self, x, y, t):
        return self.density(x, y, t) * (1 - self.fraction(x, t))

    def far_share(self, t):
        """The share of each population on the far side of the contact line x = 0 (of its whole mass)."""
        tau, s = t - self.x1, self.total.front(t)
        if tau <= 0:
            return 0.0
        w = min((4 * self.edge - 2) * tau, s)        # the fan's half width
        far = (1 - self.edge) * (s - w) + w / 2 - w ** 2 / (8 * tau)
        return far / (self.a * (self.x2 - self.x1))


class ColouredEvacuation:
    """Solution 3 with the block in two colours, "front" on x < split and "back" on split < x < s0: the
    whole block moves at one speed, so the back keeps its length s0 - split behind the front."""

    def __init__(self, k=1.0, s0=1.0, split=0.5):
        self.total = SaturatedEvacuation(k, s0)
        self.s0, self.split = s0, split

    def interface(self, t):
        return max(self.total.front(t) - (self.s0 - self.split), 0.0)

    def density_front(self, x, y, t):
        return np.where(x < self.interface(t), 1.0, 0.0)

    def density_back(self, x, y, t):
        return np.where((x >= self.interface(t)) & (x < self.total.front(t)), 1.0, 0.0)

    def evacuated_front(self, t):
        return min(self.s0 - self.total.front(t), self.split)

    def evacuated_back(self, t):
        return max(self.s0 - self.total.front(t) - self.split, 0.0)
