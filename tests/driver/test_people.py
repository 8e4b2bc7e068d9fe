"""People as counts (issue 36 item 2, docs/case-format.md): initial.people and populations.<name>.people scale
the initial density (a shape; uniform if 0) to hold exactly that many persons (sum of rho x area, rho_max in
persons/m^2), or give that many discs; refused in one line when they cannot fit under rho_max."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.driver.people import initial_people
from femcrowd.errors import InputError

from ..support import CASES

ROOM = {"model.rho_max": 5.4, "time.end": 0.1}


def initial_state(case):
    sim = Simulation(case)
    return sim, sim.model.row()


def test_people_scale_the_density_shape_to_the_count():
    """cases/room's crowd "0.8 * (x < 4)" as a shape of 57 persons: the mass at t = 0 is 57 to round-off, the
    density is constant where the shape is and 0 elsewhere."""
    sim, row = initial_state(load_case(CASES / "room", {**ROOM, "initial.people": 57}))
    assert row["mass"] == pytest.approx(57.0, rel=1e-14, abs=0)
    rho = sim.model.state.rho[0] * 5.4
    shape = sim.scene.domain.cell_average(lambda x, y, t: 0.8 * (x < 4))
    assert np.all(rho[shape == 0] == 0) and np.ptp(rho[shape == 0.8]) < 1e-14 * rho.max()
    assert rho @ sim.scene.domain.area == pytest.approx(57.0, rel=1e-14)


def test_people_without_a_density_are_uniform():
    sim, row = initial_state(load_case(CASES / "room", {**ROOM, "initial.density": 0.0, "initial.people": 100}))
    area = sim.scene.domain.area.sum()
    assert row["mass"] == pytest.approx(100.0, rel=1e-14, abs=0)
    np.testing.assert_allclose(sim.model.state.rho[0] * 5.4, 100 / area, rtol=1e-14)


def test_people_per_population():
    """cases/two-groups: 80 north, 30 south, each its own shape; both stay in the mass balance of a short run."""
    case = load_case(CASES / "two-groups", {"model.rho_max": 5.4, "time.end": 0.5, "populations.north.people": 80,
                                            "populations.south.people": 30})
    sim, row = initial_state(case)
    assert row["mass_north"] == pytest.approx(80.0, rel=1e-14) and row["mass_south"] == pytest.approx(30.0, rel=1e-14)
    h = sim.run(stop_when_empty=False).history
    assert h["mass_error_north"].max() < 1e-12 and h["mass_error_south"].max() < 1e-12
    assert initial_people(case)["populations"] == pytest.approx({"north": 80.0, "south": 30.0}, rel=1e-14)


def test_too_many_people_for_rho_max_are_refused():
    """The room's shape covers 4 m x 6 m: at most 24 x 5.4 = 129.6 persons."""
    with pytest.raises(InputError, match=r"initial.people = 130: persons do not fit under rho_max = 5.4 .* at most "
                                         r"129.6"):
        Simulation(load_case(CASES / "room", {**ROOM, "initial.people": 130}))


def test_discs_are_the_people():
    """The micro model places exactly initial.people discs, or populations.<name>.people discs per population."""
    case = load_case(CASES / "room", {**ROOM, "model.type": "micro", "initial.people": 37})
    assert Simulation(case).model.row()["count"] == 37
    case = load_case(CASES / "two-groups-micro", {"model.rho_max": 5.4, "time.end": 0.1,
                                                   "populations.north.people": 20, "populations.south.people": 9})
    row = Simulation(case).model.row()
    assert (row["count"], row["count_north"], row["count_south"]) == (29, 20, 9)


@pytest.mark.parametrize("overrides, words", [
    ({"populations.north.people": 20}, "populations.south.people = None: the discs need a number of people for "
                                       "every population"),
    ({"populations.north.people": 20.5, "populations.south.people": 9}, "populations.north.people = 20.5: the "
                                                                        "discs need a whole number"),
    ({"populations.north.people": 20, "populations.south.people": 9, "micro.count": 40}, "micro.count = 40: give "
                                                                                         "the discs by"),
])
def test_disc_counts_that_cannot_be_met_are_refused(overrides, words):
    with pytest.raises(InputError, match=words.replace("(", r"\(").replace(".", r"\.")):
        Simulation(load_case(CASES / "two-groups-micro", {"model.rho_max": 5.4, **overrides}))
