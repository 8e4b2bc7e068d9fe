"""Scenes as engineers build them (docs/scenes.md): door schedules, inflow sources, measurement lines and
areas, against exact answers and the invariants of the model."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.driver.measurements import line_facets
from femcrowd.macro.exact import SaturatedEvacuation
from femcrowd.mesh.floorplan import build_mesh
from femcrowd.micro.sampling import HEX_PACKING
from femcrowd.studies.recommended import FAST_STEP

from ..support import CASES, unit_square


def macro_run(case_dir, overrides):
    result = Simulation(load_case(case_dir, overrides)).run(stop_when_empty=False)
    assert result.summary["status"] == "completed"
    return result


def assert_invariants(history, tol=1e-10):
    """Mass balance (with inflow), 0 <= rho <= 1, p >= 0, complementarity, on every row."""
    assert history["mass_error"].max() < tol
    assert history["min_density"].min() >= 0.0
    assert history["max_density"].max() <= 1 + 1e-9
    assert history["min_pressure"].min() >= 0.0
    assert history["complementarity"].max() < 1e-9
    assert history["pressure_unsaturated"].max() == 0.0


# --- door schedules -------------------------------------------------------------------------------

def test_an_exit_that_opens_at_t0_shifts_the_exact_evacuation_by_t0():
    """Exact solution 3 with its exit closed until t0: nothing leaves before t0 (the block rests against
    the closed door), then evacuated(t) follows the exact curve s0 - s(t - t0) as closely as the run
    with the exit open from t = 0 follows s0 - s(t)."""
    t0, span = 0.2, 0.3
    exact = SaturatedEvacuation(k=1.0, s0=1.0)
    free = macro_run(CASES / "saturated-exit", {"time.end": span}).history
    door = macro_run(CASES / "saturated-exit", {"time.end": t0 + span, "boundary.open": {"exit": [[t0, np.inf]]}})
    h = door.history
    closed = h["time"] <= t0
    assert np.all(h["evacuated"][closed] == 0.0)
    assert np.any(np.isclose(h["time"], t0, rtol=0, atol=1e-14))    # a step lands on the opening
    assert_invariants(h)
    after = ~closed
    error_door = np.abs(h["evacuated"][after] - [exact.evacuated(t - t0) for t in h["time"][after]])
    error_free = np.abs(free["evacuated"] - [exact.evacuated(t) for t in free["time"]])
    assert error_door.max() <= 1.05 * error_free.max() + 1e-3, (error_door.max(), error_free.max())
    assert error_door.max() < 0.03   # ~h of the channel mesh (0.1), as in the convergence study


def test_a_door_closing_on_a_saturated_crowd_keeps_every_invariant():
    """The exit of exact solution 3 closes on the saturated block while it is pushed out, then opens
    again: the closed room's gauge and the warm start of the other door state keep the invariants."""
    schedule = {"exit": [[0.0, 0.1], [0.25, np.inf]]}
    h = macro_run(CASES / "saturated-exit", {"time.end": 0.4, "boundary.open": schedule}).history
    assert_invariants(h)
    shut = (h["time"] > 0.1) & (h["time"] <= 0.25)
    assert np.ptp(h["evacuated"][shut]) == 0.0 and h["evacuated"][shut][0] > 0
    assert h["max_pressure"][shut].max() > 0        # the crowd presses against the closed door
    assert h["evacuated"][-1] > h["evacuated"][shut][-1]


def test_closing_one_of_two_doors_reroutes_within_one_step():
    """two-exits: the wide door closes at t = 1; at a probe next to it the desired velocity pointed
    to it before and points away from it, toward the narrow door, from the first step after t = 1."""
    case = load_case(CASES / "two-exits", {"time.end": 1.5, "boundary.open": {"exit_wide": [[0, 1]]}})
    sim = Simulation(case)
    state, boundary = sim.model.state, sim.scene.boundary
    probe = sim.scene.domain.locate(np.array([[18.0, 6.0]]))[0]
    directions = []
    while state.t < 1.5:
        u = sim.scene.populations[0].velocity.cells(boundary.at(state.t))[probe]   # the U of the coming step
        directions.append((state.t, u))
        sim.model.step(1.5)
    before = [u for t, u in directions if t < 1.0]
    after = [(t, u) for t, u in directions if t >= 1.0]
    assert after[0][0] == 1.0                     # a step landed on the change
    assert all(u[0] > 0.9 for u in before)        # toward the wide door (x = 20)
    to_narrow = np.array([14.5, 0.0]) - [18.0, 6.0]
    assert all(u @ to_narrow / np.linalg.norm(to_narrow) > 0.5 for _, u in after)


def test_micro_walls_follow_the_doors(tmp_path):
    """Discs of two-exits with the wide door closed from t = 0.5: none leaves through it afterwards, the
    discs near it turn toward the narrow door, and no disc crosses the closed door."""
    case = load_case(CASES / "two-exits", {"model.type": "micro", "time.end": 3.0, "micro.count": 60,
                                           "initial.density": "0.7 * (x > 16) * (y > 4) * (y < 8)",
                                           "boundary.open": {"exit_wide": [[0, 0.5]]}})
    result = Simulation(case).run(stop_when_empty=False)
    h = result.history
    assert h["outside"].max() == 0
    late = h["time"] > 0.5 + 1e-9
    assert np.ptp(h["evacuated"][late]) == 0   # nobody reaches the narrow door in 2.5 s from x > 16
    assert h["evacuated"][late][0] > 0         # some left through the wide door while it was open
    assert result.state.q[:, 0].max() < 20.0


def test_a_case_without_the_new_keys_adds_nothing_per_step():
    sim = Simulation(load_case(CASES / "room", {"time.end": 0.5}))
    assert sim.model.solver.before_step == [] and sim.model.solver.after_step == []
    assert sim.scene.boundary.changes == [] and sim.model.sources is None and sim.model.measurements is None
    result = sim.run()
    assert result.measurements is None and "inflow" not in result.history


def write_scene(here, plan, case):
    """The plan (plan.toml, meshed: plan.msh) and the case (case.toml) of a test's scene in the folder `here`."""
    (here / "plan.toml").write_text(plan)
    build_mesh(here / "plan.toml")
    (here / "case.toml").write_text(case)


# --- inflow sources -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def channel(tmp_path_factory):
    """A 4 m x 1 m channel: "entrance" at x = 0, "exit" at x = 4, and its case (U = (1, 0))."""
    here = tmp_path_factory.mktemp("channel")
    write_scene(here, 'size = 0.1\n[outer]\npoints = [[0, 0], [4, 0], [4, 1], [0, 1]]\n'
                      '[[exits]]\nname = "entrance"\nfrom = [0, 0]\nto = [0, 1]\n'
                      '[[exits]]\nname = "exit"\nfrom = [4, 0]\nto = [4, 1]\n',
                      '[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["exit"]\n'
                      '[velocity]\ntype = "field"\nux = 1.0\n[time]\nend = 2.0\n'
                      '[[sources]]\nboundary = "entrance"\nflow = 0.3\nstart = 0.5\nend = 1.5\n')
    return here


def test_inflow_into_an_empty_channel_is_flow_times_length_times_duration(channel):
    result = macro_run(channel, {})
    h = result.history
    assert h["inflow"][-1] == pytest.approx(0.3 * 1.0 * 1.0, rel=1e-12, abs=0)
    assert h["queued"].max() == 0.0
    assert h["mass"][-1] == pytest.approx(0.3, rel=1e-12)
    assert np.all(h["inflow"][h["time"] <= 0.5] == 0.0)
    assert_invariants(h)


def test_a_blocked_entrance_queues_and_the_balance_holds(channel):
    """flow 3 per metre per second at speed 1 saturates the channel: what cannot enter waits outside,
    arrived = inflow + queued and mass + evacuated = inflow to 1e-10, the density never exceeds 1."""
    h = macro_run(channel, {"sources": [{"boundary": "entrance", "flow": 3.0, "start": 0.0, "end": 1.0}],
                            "time.end": 2.5}).history
    arrived = 3.0 * np.minimum(h["time"], 1.0)
    assert h["queued"].max() > 1.0
    np.testing.assert_allclose(h["inflow"] + h["queued"], arrived, rtol=1e-10, atol=1e-12)
    assert_invariants(h)
    assert h["queued"][-1] < h["queued"].max()   # the queue drains once the arrivals stop


def test_micro_source_places_discs_without_overlap_at_the_rate(channel):
    case = load_case(channel, {"model.type": "micro", "sources": [{"boundary": "entrance", "flow": 0.5}],
                               "micro.radius": 0.1, "time.end": 3.0})
    result = Simulation(case).run(stop_when_empty=False)
    h = result.history
    # 0.5 / rho_max x packing / (pi r^2) discs per metre per second over 1 m for 3 s
    expected = 0.5 * np.pi / (2 * np.sqrt(3)) / (np.pi * 0.01) * 3.0
    assert h["inflow"][-1] + h["queued"][-1] == pytest.approx(expected, abs=1.0)
    assert h["inflow"][-1] >= 0.9 * expected
    assert np.all(h["count"] + h["evacuated"] == h["inflow"])
    assert h["max_overlap"].max() < 1e-3 * 0.1


def one_late_disc(channel, rate):
    """The channel in micro: a source of `rate` discs per second for 12 s (r = 0.1), run to the end."""
    flow = rate * np.pi * 0.1 ** 2 / HEX_PACKING   # discs per second through the 1 m entrance (driver/sources.py)
    case = load_case(channel, {"model.type": "micro", "micro.radius": 0.1, "time.end": 20.0, "output.every": 20.0,
                               "sources": [{"boundary": "entrance", "flow": flow, "start": 0.0, "end": 12.0}]})
    return Simulation(case).run()


def test_a_disc_run_that_starts_empty_reports_when_its_last_person_left(channel):
    """Issue 25: a run that starts empty and fills from a source. 0.15 discs/s for 12 s: one disc arrives at
    t = 6.7 s and walks the 4 m out at 1 m/s before the source ends (the second would come at 13.3 s): the
    evacuation time is the step of its exit crossing, not the first step nor the end of the arrivals."""
    result = one_late_disc(channel, 0.15)
    h = result.history
    assert h["inflow"][-1] == 1 and h["evacuated"][-1] == 1
    left = h["time"][np.flatnonzero(np.diff(h["evacuated"]) > 0)[-1] + 1]   # the step it crossed the exit
    assert 10.0 < left < 12.0
    assert result.summary["evacuation_time"] == left
    assert result.summary["final_time"] == pytest.approx(12.0)   # the run stops once the arrivals are over


def test_a_run_nobody_entered_has_no_evacuation_time(channel):
    """0.05 discs/s for 12 s: 0.6 of a disc, nobody arrives; nobody left either."""
    result = one_late_disc(channel, 0.05)
    assert result.history["inflow"][-1] == 0
    assert result.summary["evacuation_time"] is None


def test_a_macro_run_that_starts_empty_reports_when_its_crowd_left(channel):
    """The macro channel filled by its source over [0.5, 1.5] s at speed 1: the mass is below the empty threshold
    from the step the last of it crosses the exit at x = 4 on (5.5 s, later by the upwind scheme's spreading),
    not at the first step."""
    result = Simulation(load_case(channel, {"time.end": 8.0})).run()
    h, t = result.history, result.summary["evacuation_time"]
    empty = result.summary["final_time"]
    inside = h["mass"] > 1e-4 * h["inflow"]   # time.empty_fraction, the default
    assert 5.5 < t < 8.0 and t == h["time"][np.flatnonzero(inside)[-1] + 1] and empty == t


#: the prediction of each kind of step: explicit upwind, the fast step, implicit-godunov and backward Euler at three
#: times the median cell's CFL step
STEPS = pytest.mark.parametrize("step", [
    {}, FAST_STEP,
    {"scheme.transport": "implicit-godunov", "time.cfl_quantile": 0.5, "time.cfl": 3.0},
    {"scheme.transport": "implicit", "time.cfl_quantile": 0.5, "time.cfl": 3.0},
], ids=["upwind", "fast", "implicit-godunov-3", "implicit-3"])


@pytest.fixture(scope="module")
def stream(tmp_path_factory):
    """A 12 m x 2 m corridor: people arrive at q = 1 /(m s) through its west side and walk at v = 1.3 m/s to the
    east side, all exit (U = (v, 0))."""
    here = tmp_path_factory.mktemp("stream")
    write_scene(here, 'size = 0.25\n[outer]\npoints = [[0, 0], [12, 0], [12, 2], [0, 2]]\n'
                      '[[exits]]\nname = "entrance"\nfrom = [0, 2]\nto = [0, 0]\n'
                      '[[exits]]\nname = "exit"\nfrom = [12, 0]\nto = [12, 2]\n',
                      '[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["exit"]\n'
                      '[velocity]\nspeed = 1.3\n[time]\nend = 15.0\n[output]\nevery = 15.0\n'
                      '[[sources]]\nboundary = "entrance"\nflow = 1.0\n')
    return here


@STEPS
def test_a_steady_stream_from_a_source_is_as_dense_as_its_flow_and_speed_make_it(stream, step):
    """A free stream of flow q at speed v has the density q / v (0.769 here): downstream of the entrance
    (3 < x < 9, reached by t = 7 s) the run holds it within 2 % at t = 15 s whatever the step. Everyone who
    arrived entered (inflow = q |entrance| t exactly, nothing queued): an implicit step takes the arrivals in its
    solve, and a source's cell takes what the step carries out of it as well as its free space at the step's start
    (macro/inflow.py; docs/scenes.md, "Sources at a large step")."""
    line = {"measure.lines": [{"name": "near", "from": [1.0, 0.0], "to": [1.0, 2.0]}]}
    simulation = Simulation(load_case(stream, {**step, **line}))
    result = simulation.run(stop_when_empty=False)
    h = result.history
    assert h["inflow"][-1] == pytest.approx(1.0 * 2.0 * 15.0, rel=1e-12) and h["queued"].max() == 0.0
    assert_invariants(h, tol=1e-12)
    # a line 1 m from the entrance: once steady, q |entrance| per second crosses it
    count, time = result.measurements["near_count"], result.measurements["time"]
    assert np.diff(np.interp([10.0, 15.0], time, count))[0] == pytest.approx(1.0 * 2.0 * 5.0, rel=1e-6)
    domain, rho = simulation.model.solver.domain, simulation.model.state.density
    x = domain.centroid[:, 0]
    downstream = (x > 3.0) & (x < 9.0)
    held = np.sum(domain.area[downstream] * rho[downstream]) / np.sum(domain.area[downstream])
    assert held == pytest.approx(1.0 / 1.3, rel=2e-2)


def short_stream(here, exit_span, capped, end, doors=""):
    """The corridor of `stream` 6 m long (its exit on x = 6 over y in `exit_span`, interior `doors` of the plan):
    people arrive at 1 /(m s) through its west side and walk at 1.3 m/s, the boundary `capped` has a capacity of
    0.5 /(m s), the run ends at `end`."""
    low, high = exit_span
    write_scene(here, 'size = 0.25\n[outer]\npoints = [[0, 0], [6, 0], [6, 2], [0, 2]]\n'
                      '[[exits]]\nname = "entrance"\nfrom = [0, 2]\nto = [0, 0]\n'
                      f'[[exits]]\nname = "exit"\nfrom = [6, {low}]\nto = [6, {high}]\n' + doors,
                      '[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["exit"]\n'
                      f'[boundary.capacity]\n{capped} = 0.5\n[velocity]\nspeed = 1.3\n'
                      f'[time]\nend = {end}\n[output]\nevery = {end}\n'
                      '[[sources]]\nboundary = "entrance"\nflow = 1.0\n')


@STEPS
def test_a_source_behind_a_jam_queues_outside_at_any_step(tmp_path, step):
    """The same corridor, 6 m long, emptied by a 0.5 m exit of capacity 0.5 /(m s): the jam fills it back to the
    entrance, and what cannot enter waits outside. The room an implicit step adds to a source's cell is bounded by
    the free space of the rest of its part of the floor: the corridor never holds more than its 12 m^2, and
    arrived = inflow + queued to round-off."""
    short_stream(tmp_path, (0.75, 1.25), "exit", 20.0)
    h = macro_run(tmp_path, step).history
    assert_invariants(h, tol=1e-12)
    assert h["mass"].max() <= 12.0 * (1 + 1e-12) and h["mass"][-1] > 11.9
    assert h["queued"][-1] > 15.0
    np.testing.assert_allclose(h["inflow"] + h["queued"], 2.0 * h["time"], rtol=1e-12)
    assert h["evacuated"][-1] <= 0.25 * 20.0 * (1 + 1e-12)   # the exit passes its capacity, no more


@pytest.mark.parametrize("door", [0.5, 0.75])
@pytest.mark.parametrize("step", [{}, FAST_STEP], ids=["upwind", "fast"])
def test_a_source_behind_a_door_at_capacity_fills_its_room_then_queues(tmp_path, step, door):
    """The corridor of `stream`, 6 m long, with an interior door of capacity 0.5 /(m s) at x = `door`: the 2 /s
    arriving fill the room in front of the door, which then passes exactly its 1 /s (at the fast step the cap is
    in the solve, macro/transport/capped.py) and the rest waits outside; arrived = inflow + queued and the
    invariants to round-off. The room, saturated with its only door at capacity, is a closed room of the
    projection (its door nodes push back like walls: Capacities.rooms); the door at 0.75 m stopped the run with
    a singular factorisation at either step."""
    short_stream(tmp_path, (0.0, 2.0), "door", 6.5, f'[[doors]]\nname = "door"\nfrom = [{door}, 0]\nto = [{door}, 2]\n')
    h = macro_run(tmp_path, step).history
    assert_invariants(h, tol=1e-12)
    np.testing.assert_allclose(h["inflow"] + h["queued"], 2.0 * h["time"], rtol=1e-12)
    assert h["flow_door"].max() <= 1.0 * (1 + 1e-12)
    late = h["time"] > 3.0
    assert np.allclose(h["flow_door"][late], 1.0, rtol=1e-9) and h["queued"][-1] > 3.0


# --- measurements ---------------------------------------------------------------------------------

def test_lines_at_the_exit_count_exactly_the_evacuated_mass():
    """cases/room: a line on the door and one 1 cm inside it count the evacuated mass (to round-off); a
    line across the cells of the room (x = 5) counts the mass that crossed it, which lies right of it."""
    lines = [{"name": "door", "from": [10, 2.5], "to": [10, 3.5]},
             {"name": "inside", "from": [9.99, 2.4], "to": [9.99, 3.6]},
             {"name": "middle", "from": [5, 0], "to": [5, 6]}]
    areas = [{"name": "front", "polygon": [[8, 2], [10, 2], [10, 4], [8, 4]]}]
    result = macro_run(CASES / "room", {"time.end": 8.0, "measure.lines": lines, "measure.areas": areas})
    m, h = result.measurements, result.history
    np.testing.assert_allclose(m["door_count"], h["evacuated"], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(m["inside_count"], h["evacuated"], rtol=1e-10, atol=1e-12)
    assert h["evacuated"][-1] > 1.0
    assert np.all(np.diff(m["middle_count"]) >= -1e-12)
    assert 0 <= m["front_density"].min() and m["front_density"].max() <= 1.0 + 1e-9
    assert m["front_pressure"].max() > 0 and m["front_speed"].max() > 0


def test_a_line_along_interior_edges_counts_the_mass_that_crossed_it():
    """On a structured mesh the line x = 1/2 follows edges: its count is exactly the mass now right of it
    minus the mass there at t = 0 (nothing leaves: no exit)."""
    domain = unit_square(16)
    facets, sign = line_facets(domain, np.array([0.5, 0.0]), np.array([0.5, 1.0]))
    assert np.allclose(domain.midpoint[facets, 0], 0.5) and domain.length[facets].sum() == pytest.approx(1.0)
    assert np.all(sign == np.where(domain.centroid[domain.f2t[0][facets], 0] < 0.5, 1, -1))


def test_micro_line_at_the_exit_counts_the_evacuated_discs():
    lines = [{"name": "door", "from": [8, 2.1], "to": [8, 2.9]}]
    case = load_case(CASES / "narrow-door-micro", {"time.end": 4.0, "measure.lines": lines})
    result = Simulation(case).run(stop_when_empty=False)
    assert result.history["evacuated"][-1] > 0
    np.testing.assert_array_equal(result.measurements["door_count"], result.history["evacuated"])


def test_an_exit_that_never_opens_is_a_wall_for_the_whole_run():
    sim = Simulation(load_case(CASES / "two-exits", {"time.end": 5.0, "boundary.open": {"exit_narrow": []}}))
    assert sim.scene.boundary.at(0.0).open == ("exit_wide",) and sim.scene.boundary.at(1e9).open == ("exit_wide",)
    h = sim.run().history
    assert np.all(h["evacuated_exit_narrow"] == 0.0) and h["evacuated_exit_wide"][-1] > 0


# --- ridges of the distance field ------------------------------------------------------------------

def test_two_doors_in_one_wall_empty_the_room(tmp_path):
    """Two doors in the wall y = 0 of a 6 m x 4 m room: the ridge x = 3 between them runs into that wall.
    Each ridge cell heads for its own nearest door (docs/model.md), so the room empties to 1e-9 of the
    crowd (the P1 gradient of the joint distance there kept a layer at the wall for good), every ridge
    cell's U is a descent direction of d, and the cells off the ridge keep the joint field's gradient."""
    write_scene(tmp_path, 'size = 0.25\n[outer]\npoints = [[0, 0], [6, 0], [6, 4], [0, 4]]\n'
                          '[[exits]]\nname = "left"\nfrom = [0.5, 0]\nto = [1.5, 0]\n'
                          '[[exits]]\nname = "right"\nfrom = [4.5, 0]\nto = [5.5, 0]\n',
                          '[mesh]\nfile = "plan.msh"\n[boundary]\nexits = ["left", "right"]\n'
                          '[initial]\ndensity = 0.5\n[time]\nend = 60.0\nempty_fraction = 1e-9\n')
    sim = Simulation(load_case(tmp_path))
    summary = sim.run().summary
    assert summary["evacuation_time"] < 20.0    # the last person from the far corner walks ~5 m
    model = sim.model
    velocity, exits = model.solver.velocities[0], model.solver.boundary.at(0.0)
    U, d = velocity.cells(exits), velocity.distance[exits.open]
    t, p = model.domain.triangles, model.domain.points
    grad = np.linalg.solve(np.stack([p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]], axis=1),
                           np.stack([d[t[:, 1]] - d[t[:, 0]], d[t[:, 2]] - d[t[:, 0]]], axis=1)[..., None])[..., 0]
    ridge = np.abs(model.domain.centroid[:, 0] - 3.0) < 0.3
    off = ~ridge & (np.hypot(*grad.T) > 0.99)
    np.testing.assert_allclose(U[off], -grad[off] / np.hypot(*grad[off].T)[:, None], atol=1e-12)
    descent = np.einsum("ij,ij->i", U[ridge], grad[ridge])     # U . grad d < 0 (d at the cell's nodes)
    assert (descent < 0).all()
