"""A flow over time g(t) >= 0 (a source's arrivals, ``[[sources]]`` flow or rate): a number, an expression of t
(femcrowd.expressions, never eval) or a table of (t, g) pairs, linear between them and 0 outside them.

What a model needs of it is the amount brought during a step, the integral of g over [a, b]: exact for a number
and a table (the table's integral is the trapezoidal rule on its own points), 8-point Gauss-Legendre for an
expression (exact to round-off for a smooth g over a time step; a jump inside a step is integrated to within
that step's share of the jump: give a table for a timetable). g = level x shape(t), with shape = 1 for a
number, so that a constant flow is computed as level x (b - a), as it always was.
"""

import math

import numpy as np

from .errors import InputError
from .expressions import Expression

#: the Gauss-Legendre points of an expression's integral over one step
GAUSS_POINTS = 8
#: the points at which an expression is checked for g >= 0 when a case is loaded
CHECK_POINTS = 1001


def table_error(value) -> str | None:
    """Why `value` is not a table of (t, g) pairs: at least two, finite numbers, g >= 0, t not decreasing (equal
    times make a jump); None if it is one."""
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    if len(value) < 2 or not all(isinstance(p, list) and len(p) == 2 and all(map(number, p)) for p in value):
        return "expected a table of at least two [t, value] pairs of finite numbers"
    for (t0, _), (t1, g) in zip(value, value[1:]):
        if t1 < t0:
            return f"the times must not decrease: {t1:g} after {t0:g}"
    negative = [g for _, g in value if g < 0]
    if negative:
        return f"a flow is >= 0, not {negative[0]:g}"
    return None


class Profile:
    """g(t) >= 0 given as a number, an expression string of t or a list of [t, g] pairs (checked by the case
    schema); ``origin``: the (file, key) named by the errors found while it is evaluated."""

    def __init__(self, value, origin=None):
        self.value, self.origin = value, origin
        self.expression = self.times = None
        if isinstance(value, str):
            self.level = 1.0
            self.expression = Expression(value, ("t",), origin)
        elif isinstance(value, list):
            self.level = 1.0
            self.times, self.values = np.array(value, float).T
            steps = np.diff(self.times)
            self.slopes = np.divide(np.diff(self.values), steps, out=np.zeros_like(steps), where=steps > 0)
            self.cumulative = np.concatenate([[0.0], np.cumsum(0.5 * steps * (self.values[:-1] + self.values[1:]))])
        else:
            self.level = float(value)

    @property
    def last(self) -> float:
        """The last time at which g may be positive (inf but for a table)."""
        return math.inf if self.times is None else float(self.times[-1])

    def __call__(self, t) -> np.ndarray:
        """g(t) / level at the times t (an array)."""
        t = np.asarray(t, float)
        if self.expression is not None:
            g = self.expression.of(t=t)
            if (g < 0).any():
                k = np.flatnonzero(g < 0)[0]
                raise InputError(*self.origin, self.value, f"a flow is >= 0, but this gives {g.flat[k]:.6g} at "
                                 f"t = {t.flat[k]:.6g}")
            return g
        if self.times is None:
            return np.ones_like(t)
        inside = (t >= self.times[0]) & (t <= self.times[-1])
        return np.where(inside, np.interp(t, self.times, self.values), 0.0)

    def check(self, start: float, end: float) -> None:
        """An expression's g >= 0 at CHECK_POINTS times of [start, end] (the error names the file and key)."""
        if self.expression is not None:
            self(np.linspace(start, end, CHECK_POINTS))

    def amount(self, a: float, b: float) -> float:
        """The integral of g / level over [a, b], a < b."""
        if self.expression is not None:
            from scipy.integrate import fixed_quad  # here: the case layer imports this module, and no scipy

            return float(fixed_quad(self, a, b, n=GAUSS_POINTS)[0])
        if self.times is None:
            return b - a
        return float(np.diff(self._primitive(np.array([a, b])))[0])

    def _primitive(self, t: np.ndarray) -> np.ndarray:
        """The integral of a table's g from its first time to t: exact for the piecewise linear g."""
        ts = self.times
        k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
        s = np.clip(t, ts[0], ts[-1]) - ts[k]
        return self.cumulative[k] + s * (self.values[k] + 0.5 * self.slopes[k] * s)


def amounts(profiles, start: np.ndarray, end: np.ndarray, t: float, dt: float) -> np.ndarray:
    """The integral of each profile's g / level over [t, t + dt] & [start, end] (one entry per profile)."""
    lo, hi = np.maximum(t, start), np.minimum(t + dt, end)
    return np.array([p.amount(a, b) if b > a else 0.0 for p, a, b in zip(profiles, lo, hi)])
