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


def test_the_maximum_is_refined_on_first_use_only(monkeypatch):
    """r* is refined when a flux first needs it (demand, supply), never for a law that is only built (the check of
    the case, f = 1 beside a population's own law), and to the same numbers as when every law refined it at once
    (the values of commit 9cdafa4, printed with repr)."""
    before = {("predtechenskii", 5.4): 0.9259259259259252, ("weidmann", 5.4): 0.32419725629027707,
              ("linear", 1.0): 0.49999999972374587, ("constant", 1.0): 0.9999999999999996}
    calls = []
    refine = SpeedLaw._refine_maximum
    monkeypatch.setattr(SpeedLaw, "_refine_maximum", lambda law, *a: calls.append(law.spec) or refine(law, *a))
    laws = {key: SpeedLaw(*key) for key in before}
    assert not calls
    for (spec, _), law in laws.items():
        law.demand(np.array([0.5]))
        assert law.r_star == before[spec, _] and calls.count(spec) == 1


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


#: Predtechenskii and Milinskii (1978), horizontal path (GOST 12.1.004-91 appendix 2): D (m^2/m^2), v (m/min), q (m/min)
PM_TABLE = [(0.01, 100, 1.0), (0.05, 100, 5.0), (0.1, 80, 8.0), (0.2, 60, 12.0), (0.3, 47, 14.1), (0.4, 40, 16.0),
            (0.5, 33, 16.5), (0.6, 27, 16.2), (0.7, 23, 16.1), (0.8, 19, 15.2), (0.9, 15, 13.5)]


def test_predtechenskii_is_the_published_table():
    """f(rho) = v(D) / v(0) with D = 0.1 m^2 x rho (persons/m^2): the table's speeds at its densities (rho_max = 9
    persons/m^2, D = 0.9 at saturation, so every row is in [0, 1]), its flows q = D v linear between them (D = 0.25:
    q = 13.05, v = 52.2 m/min), v = 15 m/min beyond the last row, and q = D v at every row."""
    law = SpeedLaw("predtechenskii", rho_max=9.0)
    for d, v, q in PM_TABLE:
        assert law(np.array(d / 0.9)) == pytest.approx(v / 100, abs=1e-12)
        assert d * v == pytest.approx(q, abs=0.051)   # the published q, rounded to 0.1 m/min
    assert law(np.array(0.25 / 0.9)) == pytest.approx(52.2 / 100, abs=1e-12)
    assert law(np.array(0.0)) == 1.0
    assert SpeedLaw("predtechenskii", rho_max=12.0)(np.array([0.8, 1.0])) == pytest.approx([0.15, 0.15], abs=1e-12)
    # rho_max = 5.4 persons/m^2: D = 0.54 at saturation, q = 16.5 + 0.4 (16.2 - 16.5) = 16.38, v = 30.33 m/min
    assert SpeedLaw("predtechenskii", rho_max=5.4).f1 == pytest.approx(16.38 / 0.54 / 100, abs=1e-12)


@pytest.mark.parametrize("rho_max", [1.0, 5.4, 9.0])   # up to D = 0.9, the densest row
def test_predtechenskii_pushes_at_saturation_and_carries_more_than_weidmann(rho_max):
    """f in [0, 1], non-increasing, f(1) > 0 (people still walk at the densest: the projection acts, no push needed),
    g = r f unimodal (Godunov's demand and supply); with 1.67 m/s and 5.4 persons/m^2 the law carries 2.75
    persons/(m s) at most (q = 16.5 m/min at D = 0.5: 16.5 / 60 / 0.1), Weidmann's 1.22."""
    law = SpeedLaw("predtechenskii", rho_max=rho_max)
    r = np.linspace(0, 1, 10001)
    f = law(r)
    assert f.min() > 0 and f.max() == 1.0 and np.all(np.diff(f) <= 1e-15)
    assert law.saturates and law.unimodal
    if rho_max == 5.4:
        assert 100 / 60 * 5.4 * law.flux(np.array(law.r_star)) == pytest.approx(16.5 / 6, rel=1e-6)
        assert 5.4 * law.r_star == pytest.approx(5.0, abs=1e-6)
