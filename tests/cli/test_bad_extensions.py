"""Bad input to the extensions (speed laws, populations, disc strategies) through the real CLI: one line
naming file, key and value, exit code 2, a pre-existing output directory left as it was."""

import pytest
from click.testing import CliRunner

from femcrowd.cli import main

from .test_bad_input import BASE, GOOD_MESH, assert_run_refused, edit, write_case

TWO = edit("[initial]\ndensity = 0.5\n", '[populations.a]\ndensity = "0.5 * (x < 0.5)"\n'
           '[populations.b]\ndensity = "0.5 * (x >= 0.5)"\n')

#: id -> (case.toml text, --set overrides, key, value, words of the message)
BAD = {
    "unknown speed law": (edit('type = "exits"', 'type = "exits"\nspeed_law = "weidman"'), (),
                          "velocity.speed_law", "weidman", "unknown name 'weidman'"),
    "speed law above 1": (edit('type = "exits"', 'type = "exits"\nspeed_law = "2 - rho"'), (),
                          "velocity.speed_law", "2 - rho", "not a finite number in [0, 1]"),
    "negative speed law": (edit('type = "exits"', 'type = "exits"\nspeed_law = "1 - 2 * rho"'), (),
                           "velocity.speed_law", "1 - 2 * rho", "not a finite number in [0, 1]"),
    "speed law not finite": (edit('type = "exits"', 'type = "exits"\nspeed_law = "1 - log(1 - rho)"'), (),
                             "velocity.speed_law", "1 - log(1 - rho)", "not a finite number"),
    "speed law increases": (edit('type = "exits"', 'type = "exits"\nspeed_law = "0.5 + 0.5 * rho"'), (),
                            "velocity.speed_law", "0.5 + 0.5 * rho", "f increases with the density"),
    "speed law of x": (edit('type = "exits"', 'type = "exits"\nspeed_law = "1 - x * rho"'), (),
                       "velocity.speed_law", "1 - x * rho", "unknown name 'x' (variables: rho"),
    "speed law is a number": (BASE, ("velocity.speed_law=0.5",), "velocity.speed_law", "0.5",
                              "or an expression in rho"),
    "speed law with compressive": (edit('type = "exits"', 'type = "exits"\nspeed_law = "linear"'),
                                   ('scheme.transport="compressive"',), "scheme.transport", "compressive",
                                   "use one of 'upwind', 'muscl'"),
    "population exits not exits": (TWO.replace('[populations.a]\n', '[populations.a]\nexits = ["door"]\n'), (),
                                   "populations.a.exits", "['door']", "'door' is not an exit"),
    "population exits empty": (TWO.replace('[populations.a]\n', '[populations.a]\nexits = []\n'), (),
                               "populations.a.exits", "[]", "is empty"),
    "populations above rho_max": (TWO.replace('"0.5 * (x >= 0.5)"', '"0.6"'), (), "populations",
                                  "0.5 * (x < 0.5)", "sum to 1.1 > rho_max = 1"),
    "population density above rho_max": (TWO.replace('"0.5 * (x >= 0.5)"', '"1.5"'), (),
                                         "populations.b.density", "1.5", "outside [0, rho_max = 1]"),
    "population and initial density": (TWO + "[initial]\ndensity = 0.2\n", (), "initial.density", "0.2",
                                       "each population has its own initial density"),
    "population name": (TWO.replace("[populations.b]", '[populations."b c"]'), (), "populations.b c", "",
                        "letters, digits, _ and - only"),
    "population unknown key": (TWO.replace('[populations.a]\n', '[populations.a]\nspeeed = 2\n'), (),
                               "populations.a.speeed", "2", "did you mean 'populations.a.speed'"),
    "population speed negative": (TWO.replace('[populations.a]\n', '[populations.a]\nspeed = "1 - 2 * x"\n'), (),
                                  "populations.a.speed", "1 - 2 * x", "walk away from the exits"),
    "unknown micro strategy": (BASE + '\n[model]\ntype = "micro"\n\n[micro]\nstrategy = "overtake"\n', (),
                               "micro.strategy", "overtake", "expected one of 'push', 'decelerate', 'bypass'"),
    "view angle beyond 90": (BASE, ("micro.view_angle=120",), "micro.view_angle", "120", "must be in (0, 90]"),
    "capacity not a table": (BASE, ("boundary.capacity=1.9",), "boundary.capacity", "1.9", "expected a table"),
    "capacity of no door": (BASE, ("boundary.capacity={dor=1.9}",), "boundary.capacity.dor", "1.9",
                            "did you mean 'door'"),
    "capacity not positive": (BASE, ("boundary.capacity={exit=0}",), "boundary.capacity.exit", "0",
                              "expected a capacity > 0"),
    "capacity of a wall": (BASE, ("boundary.capacity={wall=1.3}",), "boundary.capacity.wall", "1.3",
                           "has boundary edges but is not an exit"),
    "interior door capacity with muscl": (BASE, ("boundary.capacity={door=1.3}", 'scheme.transport="muscl"'),
                                          "boundary.capacity.door", "1.3",
                                          "needs a one-stage or the implicit transport"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_extension_input_is_refused_cleanly(tmp_path, name):
    toml, overrides, key, value, words = BAD[name]
    assert_run_refused(tmp_path, toml, GOOD_MESH, overrides, key, value, words)


def test_population_overrides_are_accepted(tmp_path):
    """The valid case the population errors above break: two populations, one with its own law and exits."""
    toml = TWO.replace('[populations.a]\n', '[populations.a]\nspeed_law = "linear"\nexits = ["exit"]\n')
    case = write_case(tmp_path, toml, GOOD_MESH)
    result = CliRunner().invoke(main, ["run", str(case), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 0, result.output
