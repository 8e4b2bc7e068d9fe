"""A desired speed that depends on the density (Maury, Roudneff-Chupin, Santambrogio, Venel 2011, section on
extensions): people slow down in a dense crowd, in the spirit of road-traffic models,

    U(x, rho) = f(rho) U0(x),   f non-increasing on [0, 1], 0 <= f <= 1,

with rho in units of rho_max. The prediction is then the scalar conservation law
d_t rho + div(rho f(rho) U0) = 0 (Lighthill, Whitham 1955; Richards 1956: LWR) with the flux
g(r) = r f(r) along U0. If f(1) = 0 nobody walks into a saturated crowd and the density never
exceeds 1 (no projection is needed); if f(1) > 0 people still push and the projection acts.

Laws (``[velocity] speed_law``): "constant" (f = 1, the model of docs/model.md), "linear"
(f = 1 - rho), "weidmann" (Weidmann 1993: v = v0 (1 - exp(-gamma (1/rho - 1/rho_max))),
gamma = 1.913 m^-2, rho in persons/m^2 and rho_max = model.rho_max, 5.4 m^-2 in Weidmann's
fit; v0 is velocity.speed), "predtechenskii" (Predtechenskii, Milinskii 1978, as tabulated for
horizontal paths in GOST 12.1.004-91, appendix 2: the speed v(D) against the projected density
D = a rho, a = 0.1 m^2 per person, the flow D v interpolated linearly as the standard's method does;
f = v(D) / v(0), and f = 15/100 for D >= 0.9: people still move in the densest crowd, so f(1) > 0
with no push) or an expression in rho. A law is sampled once on [0, 1]: its
range, monotonicity, the maximiser r* of g and whether g is unimodal (increasing, then
decreasing), and its Lipschitz constant (for the CFL condition).

A push p > 0 (``[velocity] push``) keeps f >= p: people in a jam still push towards the exits at
p times their desired speed, so the density can exceed 1, the projection acts and its pressure moves
the jam (docs/model.md, "A speed law whose door flow converges"). With f(1) = 0 a crowd whose
directions meet at a point (the corner of a door, the end of a wall) jams there for good: the
continuum LWR equation itself keeps it, and the mesh drains it only by numerical diffusion, so the
flow through a door falls as the mesh is refined.
"""

from functools import cached_property

import numpy as np

from ..expressions import Expression, ExpressionError

#: Weidmann (1993), the fundamental diagram of pedestrian flow on a level floor
WEIDMANN_GAMMA = 1.913  # m^-2
#: Predtechenskii and Milinskii (1978), horizontal paths, as the Russian fire-safety methods tabulate them (GOST
#: 12.1.004-91, appendix 2; femcrowd/studies/experiments.csv says where it was read): the projected density D (m^2
#: of bodies per m^2 of floor) and the speed v (m/min) of a crowd at D; "0.9 and more": v = 15 m/min
PM_DENSITY = np.array([0.01, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9])
PM_SPEED = np.array([100.0, 100.0, 80.0, 60.0, 47.0, 40.0, 33.0, 27.0, 23.0, 19.0, 15.0])
#: the horizontal projection of a person, m^2 (an adult in home clothing; 0.125 in winter clothing): D = PM_AREA x
#: persons/m^2
PM_AREA = 0.1
#: the names of the laws; anything else is an expression in rho
NAMES = ("constant", "linear", "weidmann", "predtechenskii")
#: samples of [0, 1] on which a law is checked and its constants are measured
SAMPLES = 4097
#: margin on the sampled Lipschitz constant of g (the CFL condition uses it)
LIPSCHITZ_MARGIN = 1.01


def predtechenskii(density):
    """v(D), m/min: Predtechenskii and Milinskii's speed on a horizontal path at the projected density D
    (PM_DENSITY, PM_SPEED): the flow q = D v linear between the tabulated densities (so that q is unimodal and
    v non-increasing), v constant below the first and above the last."""
    d = np.clip(density, PM_DENSITY[0], PM_DENSITY[-1])
    return np.minimum(np.interp(d, PM_DENSITY, PM_DENSITY * PM_SPEED) / d, PM_SPEED[0])   # v(0.01) / 0.01 rounds


class LawError(ValueError):
    """A speed law that is not a function f: [0, 1] -> [0, 1], finite and non-increasing."""


class SpeedLaw:
    """f(rho) on [0, 1] (rho in units of rho_max): the factor of the desired speed, and the LWR flux
    g(r) = r f(r) with its demand and supply (Lebacque 1996) when g is unimodal."""

    def __init__(self, spec, rho_max: float = 1.0, push: float = 0.0, origin=None):
        """spec: one of NAMES or an expression in rho; rho_max: the case's saturation density (persons/m^2
        for "weidmann"); push: the least f (people still push at push x their desired speed); origin: the
        (file, key) of the case that an expression's errors name (femcrowd.expressions). Raises LawError for
        a law outside [0, 1], not finite or increasing somewhere."""
        self.spec, self.push = spec, push
        if spec == "constant":
            self._f = lambda r: np.ones_like(r)
        elif spec == "linear":
            self._f = lambda r: 1.0 - r
        elif spec == "weidmann":
            c = WEIDMANN_GAMMA / rho_max
            self._f = lambda r: np.where(r > 0, -np.expm1(-c * (1.0 / np.maximum(r, 1e-300) - 1.0)), 1.0)
        elif spec == "predtechenskii":
            self._f = lambda r: predtechenskii(PM_AREA * rho_max * r) / PM_SPEED[0]
        else:
            try:
                expression = Expression(spec, variables=("rho",), origin=origin)
            except ExpressionError as err:
                raise LawError(str(err)) from None
            self._f = lambda r: expression.of(rho=r)
        if push > 0:
            law = self._f
            self._f = lambda r: np.maximum(law(r), push)
        r = np.linspace(0.0, 1.0, SAMPLES)
        with np.errstate(all="ignore"):
            try:
                f = self._f(r)
            except ExpressionError as err:
                raise LawError(f"f(rho) {err}") from None
        bad = np.flatnonzero(~np.isfinite(f) | (f < 0) | (f > 1))
        if bad.size:
            raise LawError(f"f(rho) = {f[bad[0]]:.6g} at rho = {r[bad[0]]:.6g}: not a finite number in [0, 1]")
        up = np.flatnonzero(np.diff(f) > 1e-12)
        if up.size:
            k = up[0]
            raise LawError(f"f increases with the density (f({r[k]:.4g}) = {f[k]:.6g} < f({r[k + 1]:.4g}) = "
                           f"{f[k + 1]:.6g}): people do not walk faster in a denser crowd")
        self.f1 = float(f[-1])
        g = r * f
        self._sampled_maximum = float(r[np.argmax(g)])
        rising = np.diff(g[: np.argmax(g) + 1])
        falling = np.diff(g[np.argmax(g):])
        self.unimodal = bool(np.all(rising >= -1e-14) and np.all(falling <= 1e-14))
        self.lipschitz = LIPSCHITZ_MARGIN * float(np.max(np.abs(np.diff(g))) * (SAMPLES - 1))
        #: the Lipschitz constant of f itself (f(r) <= slope (1 - r) when f(1) = 0), sampled the same way
        self.slope = LIPSCHITZ_MARGIN * float(np.max(np.abs(np.diff(f))) * (SAMPLES - 1))

    @cached_property
    def r_star(self) -> float:
        """The maximiser of g: the best sample, refined where g is unimodal (on first use: a law that is only
        checked, or f = 1 where no flux needs it, never pays the 160 evaluations of the refinement)."""
        if not self.unimodal:
            return self._sampled_maximum
        return self._refine_maximum(self._sampled_maximum, 1.0 / (SAMPLES - 1))

    @property
    def constant(self) -> bool:
        """f = 1: the desired speed does not depend on the density (the linear upwind transport)."""
        return self.spec == "constant"

    @property
    def saturates(self) -> bool:
        """f(1) > 0: people push at saturation, so the density can exceed 1 and needs the projection."""
        return self.f1 > 0

    def __call__(self, rho: np.ndarray) -> np.ndarray:
        """f(rho), rho clipped to [0, 1]."""
        return self._f(np.clip(rho, 0.0, 1.0))

    def flux(self, rho: np.ndarray) -> np.ndarray:
        """g(rho) = rho f(rho) on [0, 1]."""
        r = np.clip(rho, 0.0, 1.0)
        return r * self._f(r)

    def demand(self, rho: np.ndarray) -> np.ndarray:
        """D(r) = g(min(r, r*)): the most the sender can give (unimodal g)."""
        return self.flux(np.minimum(rho, self.r_star))

    def supply(self, rho: np.ndarray) -> np.ndarray:
        """S(r) = g(max(r, r*)): the most the receiver can take (unimodal g)."""
        return self.flux(np.maximum(rho, self.r_star))

    def _refine_maximum(self, r0, width):
        """argmax of the unimodal g near the sample r0 (golden section on [r0 - w, r0 + w]): to about 1e-9,
        where g is flat to round-off."""
        a, b = max(r0 - width, 0.0), min(r0 + width, 1.0)
        ratio = (np.sqrt(5.0) - 1.0) / 2.0
        for _ in range(80):
            c, d = b - ratio * (b - a), a + ratio * (b - a)
            if self.flux(np.array(c)) >= self.flux(np.array(d)):
                b = d
            else:
                a = c
        return 0.5 * (a + b)
