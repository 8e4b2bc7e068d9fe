"""The extensions against their exact solutions (docs/extensions.md), on refinement series with observed
rates fitted on the finer pair of levels (femcrowd.studies.extensions, the tables of the docs)."""

import pytest

from femcrowd.studies.extensions import coloured_evacuation, head_on, lwr_riemann, observed_order


def check_invariants(rows, populations=()):
    for row in rows:
        assert row["mass_error"] < 1e-12
        assert row["min_density"] >= 0.0 and row["max_density"] <= 1 + 1e-9 and row["min_pressure"] >= 0.0
        assert row["complementarity"] <= 1e-9
        for name in populations:
            assert row[f"mass_error_{name}"] < 1e-12 and row[f"min_density_{name}"] >= 0.0


@pytest.mark.parametrize("kind", ["shock", "fan"])
def test_lwr_riemann_problems(kind):
    """Linear law: L1 ~ h^(1/2) or better, the shock (the fan's middle) ~ h, and never a projection."""
    rows = lwr_riemann(3, kind)
    check_invariants(rows)
    assert all(row["projection_steps"] == 0 for row in rows)
    assert observed_order(rows, "l1") > 0.5, rows
    assert observed_order(rows, "position_error") > 0.8, rows


def test_head_on_populations_coarse():
    """Two levels: the total is solution 1, each population the mixing fan, each conserved and >= 0."""
    rows = head_on(2)
    check_invariants(rows, ("east", "west"))
    for metric in ("l1", "front_error", "l1_east", "l1_west"):
        assert abs(rows[1][metric]) < abs(rows[0][metric]), (metric, rows)
    share = [abs(row["far_east"] - row["far_exact"]) for row in rows]
    assert share[1] < share[0] < 0.05


@pytest.mark.slow
def test_head_on_populations_rates():
    """Three levels (about 15 s): L1 of the total and of each population ~ h^(1/2), the share of each
    population beyond the contact line converging to the fan's 1/3."""
    rows = head_on(3)
    check_invariants(rows, ("east", "west"))
    for metric in ("l1", "l1_east", "l1_west"):
        assert observed_order(rows, metric) > 0.4, (metric, rows)
    errors = [{"far_error": row["far_east"] - row["far_exact"], "h": row["h"]} for row in rows]
    assert observed_order(errors, "far_error") > 0.4, errors


def test_saturated_evacuation_in_two_colours():
    """The total is the one-colour run (round-off); the colours move together: their L1 errors and
    evacuated masses converge."""
    rows = coloured_evacuation(3)
    check_invariants(rows, ("front", "back"))
    assert all(row["total_vs_one_colour"] < 1e-12 for row in rows)
    assert observed_order(rows, "l1") > 0.5 and observed_order(rows, "l1_back") > 0.5, rows
    for metric in ("l1_front", "evacuated_front_error", "evacuated_back_error"):
        assert observed_order(rows, metric) > 0.3, (metric, rows)
