"""Plausibility warnings (driver/plausibility.py): speeds outside 0.1-5 m/s in a case in people/m^2, Weidmann's
law with rho_max = 1, discs wider than every exit; one line each, once; none for the shipped cases."""

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd.case import load_case
from femcrowd.cli import main
from femcrowd.driver import plausibility
from femcrowd.driver.plausibility import warn_implausible
from femcrowd.driver.scene import build_scene

from ..support import CASES


@pytest.mark.parametrize("case, override, warning", [
    ("bottleneck", "velocity.speed=134", "velocity.speed = 134: a desired speed of up to 134 m/s, outside the "
                                         "0.1-5 m/s"),
    ("bottleneck", "velocity.speed=0.05", "velocity.speed = 0.05: a desired speed of up to 0.05 m/s"),
    ("bottleneck", 'velocity.speed="1.2 + 10 * (x > 5)"', "a desired speed of up to 11.2 m/s"),
    ("room", 'velocity.speed_law="weidmann"', "velocity.speed_law = 'weidmann' with model.rho_max = 1: "
                                              "Weidmann's law is in people/m^2"),
    ("two-groups", 'populations.north.speed_law="weidmann"', "populations.north.speed_law = 'weidmann' with "
                                                              "model.rho_max = 1"),
    ("narrow-door-micro", "micro.radius=0.45", "micro.radius = 0.45: discs 0.9 m wide, wider than every exit "
                                               "(the widest, exit, is 0.8 m): no disc can leave")])
def test_each_warning_names_the_key_and_value(case, override, warning):
    [text] = warn_implausible(build_scene(load_case(CASES / case, [override])))
    assert text.startswith(f"{CASES / case / 'case.toml'}: ") and warning in text


@pytest.mark.parametrize("case, override", [
    ("room", "velocity.speed=134"),                # densities in fractions of saturation: no unit to check
    ("bottleneck", 'velocity.speed_law="weidmann"'),   # rho_max = 5.4
    ("narrow-door-micro", "micro.radius=0.39")])   # 0.78 m discs pass the 0.8 m exit
def test_no_warning_where_nothing_is_implausible(case, override):
    assert warn_implausible(build_scene(load_case(CASES / case, [override]))) == []


def test_the_speed_check_locates_no_point():
    """The desired speeds at the centroids are U per cell (a cell's centroid lies in it): the check builds no point
    locator of the mesh (10 ms at 6 000 triangles, docs/performance.md "The fixed costs removed"), and its speeds
    are those of U at the centroids located one by one."""
    scene = build_scene(load_case(CASES / "bottleneck", ["velocity.speed=134"]))
    assert "134 m/s" in warn_implausible(scene)[0]
    assert scene.domain._locator is None
    velocity, exits = scene.populations[0].velocity, scene.boundary.at(0.0)
    assert np.array_equal(velocity.at_centroids(0.0, exits), velocity.at_points(scene.domain.centroid, 0.0, exits))


def test_shipped_cases_give_no_warning():
    cases = sorted(file.parent for file in CASES.rglob("case.toml"))
    assert len(cases) > 40
    for case in cases:
        assert warn_implausible(build_scene(load_case(case))) == [], case


def test_the_warning_is_one_line_on_stderr_once(monkeypatch):
    """femcrowd info builds the scene twice (the estimate, the people): the warning is given once; in a process,
    a scene built again does not repeat it."""
    result = CliRunner().invoke(main, ["info", str(CASES / "bottleneck"), "--set", "velocity.speed=133"])
    assert result.exit_code == 0, result.output
    [line] = result.stderr.splitlines()
    assert line.startswith("femcrowd: ") and "velocity.speed = 133: a desired speed of up to 133 m/s" in line
    given = []
    monkeypatch.setattr(plausibility.log, "warning", given.append)
    build_scene(load_case(CASES / "bottleneck", ["velocity.speed=133"]))
    assert given == []
    build_scene(load_case(CASES / "bottleneck", ["velocity.speed=132"]))
    assert len(given) == 1 and "132 m/s" in given[0]
