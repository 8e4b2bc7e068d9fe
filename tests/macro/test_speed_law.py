"""Speed laws f(rho) and the LWR fluxes they give (macro/speed_law.py, macro/transport/lwr.py)."""

import numpy as np
import pytest

from femcrowd.macro.exact import lwr_riemann
from femcrowd.macro.speed_law import LawError, SpeedLaw


def test_the_named_laws():
    r = np.linspace(0, 1, 11)
    assert np.array_equal(SpeedLaw("constant")(r), np.ones(11))
    assert np.allclose(SpeedLaw("linear")(r), 1 - r)
    weidmann = SpeedLaw("weidmann", rho_max=5.4)
    # Weidmann (1993): v / v0 = 1 - exp(-1.913 (1/rho - 1/5.4)), rho in persons/m^2
    people = np.array([0.5, 1.0, 2.0, 4.0, 5.4])
    assert np.allclose(weidmann(people / 5.4), 1 - np.exp(-1.913 * (1 / people - 1 / 5.4)))
    assert weidmann(np.array(0.0)) == 1.0 and weidmann.f1 == 0.0
    assert not weidmann.saturates and not SpeedLaw("linear").saturates and SpeedLaw("constant").saturates


def test_maximum_of_the_flux_and_unimodality():
    assert SpeedLaw("linear").r_star == pytest.approx(0.5, abs=1e-8)   # g is flat there: g(r*) to 1e-16
    weidmann = SpeedLaw("weidmann", rho_max=5.4)
    assert weidmann.unimodal
    # Weidmann's capacity: max v(rho) rho = 1.22 persons/(m s) at about 1.75 persons/m^2 with v0 = 1.34 m/s
    assert 1.34 * 5.4 * weidmann.flux(np.array(weidmann.r_star)) == pytest.approx(1.22, abs=0.01)
    assert 5.4 * weidmann.r_star == pytest.approx(1.75, abs=0.1)
    # f = 1 until 0.3, then 0.2 until 0.9, then down to 0: g = r f has two humps
    humps = SpeedLaw("where(rho < 0.3, 1, where(rho < 0.4, 1 - 8 * (rho - 0.3), where(rho < 0.9, 0.2, "
                     "2 * (1 - rho))))")
    assert not humps.unimodal


def test_godunov_demand_supply_is_the_exact_riemann_flux_of_the_linear_law():
    """min(D(a), S(b)) = g(rho(0)) with rho(x/t) the entropy solution of the Riemann problem (a | b)."""
    law = SpeedLaw("linear")
    values = np.linspace(0, 1, 41)
    for a in values:
        for b in values:
            exact = float(lwr_riemann(a, b, np.array(0.0)))
            godunov = min(law.demand(np.array(a)), law.supply(np.array(b)))
            assert godunov == pytest.approx(exact * (1 - exact), abs=1e-12), (a, b)


@pytest.mark.parametrize("spec, words", [
    ("2 - rho", "not a finite number in [0, 1]"), ("-rho", "not a finite number in [0, 1]"),
    ("1 / (rho - 0.5)", "not a finite number"), ("rho", "f increases"), ("x", "unknown name"),
    ("exp(", "syntax error"),
])
def test_bad_laws(spec, words):
    with pytest.raises(LawError, match=words.replace("[", r"\[").replace("]", r"\]")):
        SpeedLaw(spec)
