"""Route choice (velocity.route = "congestion", macro/velocity.py CongestionVelocity): the free-flow limit,
convergence of the potential with a density-dependent cost, symmetry, and a crowd that takes a farther,
wider exit when the near door queues."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.macro import MacroSolver, MacroState
from femcrowd.macro.seen_density import SeenDensity
from femcrowd.macro.speed_law import SpeedLaw
from femcrowd.macro.velocity import ROUTE_FLOOR, CongestionVelocity, ExitsVelocity
from femcrowd.mesh import Boundary

from ..support import CASES, unit_square


def congestion(domain, route_every=1.0, law="constant"):
    return CongestionVelocity(domain, Expression("1"), None, SpeedLaw(law), route_every)


def test_at_zero_density_the_route_is_the_shortest_path():
    """No crowd: no cost, the same field to the last bit as route = "shortest" (one exit)."""
    domain = unit_square(16, exits=["left"])
    exits = Boundary(domain).at(0.0)
    route = congestion(domain)
    assert route.route(0.0, np.zeros(domain.ncells), exits) and route.cost is None
    assert np.array_equal(route.cells(exits), ExitsVelocity(domain, Expression("1")).cells(exits))
    assert not route.route(0.5, np.ones(domain.ncells), exits)      # not due before route_every
    assert route.route(1.0, np.full(domain.ncells, 0.5), exits) and np.allclose(route.cost, 2.0)


def test_at_a_door_with_a_capacity_the_walk_is_the_walking_distance():
    """A capped door's queue is its wait: its potential is the walking distance whatever the density, and people
    head along the shortest paths to it; a door without a capacity keeps Hughes' potential, which grows with the
    density (Hughes' cost at capped doors made cases/route-queues diverge under refinement, docs/model.md)."""
    domain = unit_square(16, exits=["left"])
    density = 0.9 * domain.centroid[:, 0]
    for capacity in (None, {"left": 0.2}):
        exits = Boundary(domain, capacity=capacity).at(0.0)
        route, free = congestion(domain), ExitsVelocity(domain, Expression("1"))
        assert route.route(0.0, density, exits)
        geodesic = free.potential(exits)
        if capacity is None:
            assert np.all(route.potential(exits) >= geodesic) and route.potential(exits).max() > 2 * geodesic.max()
        else:
            assert np.array_equal(route.potential(exits), geodesic)
            assert np.array_equal(route.cells(exits), free.cells(exits))


def test_an_unchanged_cost_is_not_solved_again(monkeypatch):
    """Two doors without a capacity are solved together; a route whose cost is the one of the last solve bit for bit
    (a crowd that did not move, or none) reuses the potentials, and they are those of a fresh solve."""
    domain = unit_square(16, exits=["left", "right"])
    exits = Boundary(domain).at(0.0)
    route, calls = congestion(domain), []
    solve_each = route.eikonal.solve_each
    monkeypatch.setattr(route.eikonal, "solve_each", lambda edges, cost: calls.append(len(edges)) or
                        solve_each(edges, cost))
    density = 0.8 * (domain.centroid[:, 0] > 0.6)
    route.route(0.0, density, exits)
    first = route.cells(exits).copy()
    route.route(1.0, density.copy(), exits)
    assert calls == [2] and np.array_equal(route.cells(exits), first)
    route.route(2.0, 0.5 * density, exits)
    assert calls == [2, 2]
    for name in ("left", "right"):
        fresh = congestion(domain).eikonal.solve(route._edges(exits, (name,)), route.cost)
        assert route.hughes[name][0] is route.cost and np.array_equal(route.hughes[name][1], fresh)


def test_hughes_cost_sees_the_crowd_around():
    """With the macro solver's seen density (macro/seen_density.py) a saturated cell costs the cells around it
    too, and itself less than the jam's 1 / ROUTE_FLOOR; without it (the discs' density, already averaged) the
    cost is the cell's own."""
    domain = unit_square(16, exits=["left"])
    exits = Boundary(domain).at(0.0)
    centre = int(np.argmin(np.hypot(*(domain.centroid - 0.5).T)))
    around = np.flatnonzero((np.hypot(*(domain.centroid - domain.centroid[centre]).T) < 0.1))
    around = around[around != centre]
    rho = np.zeros(domain.ncells)
    rho[centre] = 1.0
    own, seen = congestion(domain), congestion(domain)
    seen.seen = SeenDensity(domain)
    own.route(0.0, rho, exits)
    seen.route(0.0, rho, exits)
    assert own.cost[centre] == 1 / ROUTE_FLOOR and np.all(own.cost[around] == 1.0)
    assert 1.0 < seen.cost[centre] < 1 / ROUTE_FLOOR and np.all(seen.cost[around] > 1.0)


def test_the_potential_converges_under_refinement():
    """Cost 1 / f(rho) = 1 + y (f = 1 - rho, rho = y / (1 + y)), exit at the bottom: phi = y + y^2 / 2 exactly;
    the cost is constant per cell, so the error is O(h)."""
    errors = []
    for n in (8, 16, 32, 64):
        domain = unit_square(n, exits=["bottom"])
        exits = Boundary(domain).at(0.0)
        route = congestion(domain)
        y = domain.centroid[:, 1]
        route.route(0.0, y / (1 + y), exits)
        phi = route.eikonal.solve(exits.edges(), route.cost)
        yn = domain.points[:, 1]
        errors.append(np.abs(phi - (yn + yn**2 / 2)).max())
    rates = np.log2(np.array(errors[:-1]) / errors[1:])
    assert errors[-1] < 5e-3 and rates.min() > 0.9, (errors, rates)


@pytest.mark.parametrize("capacity", [None, 0.2])
def test_a_symmetric_room_with_two_equal_exits_stays_symmetric(capacity):
    """A block in the middle of the unit square, exits left and right (without a capacity: Hughes' cost only; with
    the same capacity: the waits, and the walking distance): the density mirrors itself at every step to round-off,
    amplified by the cost's slope f'/f^2 (up to 400 here) over the re-solved routes (at most 5e-10 measured), and
    both exits pass the same mass."""
    domain = unit_square(16, exits=["left", "right"])
    boundary = Boundary(domain, capacity=None if capacity is None else {"left": capacity, "right": capacity})
    c = domain.centroid
    mirror = np.lexsort((c[:, 1], c[:, 0]))[np.argsort(np.lexsort((c[:, 1], 1 - c[:, 0])))]
    assert np.allclose(c[mirror], np.column_stack([1 - c[:, 0], c[:, 1]]))
    rho0 = 0.9 * ((np.abs(c[:, 0] - 0.5) < 0.3) & (np.abs(c[:, 1] - 0.4) < 0.3))
    state = MacroState.initial(rho0[None], 2)
    solver = MacroSolver(domain, boundary, [congestion(domain, route_every=0.05)])
    while state.t < 1.0:
        solver.step(state)
        assert np.abs(state.rho[0] - state.rho[0][mirror]).max() <= 1e-9
    assert state.evacuated.sum() > 0.1 * rho0 @ domain.area
    assert abs(state.evacuated[0, 0] - state.evacuated[0, 1]) <= 1e-9 * state.evacuated.sum()


def test_the_routes_of_a_standing_crowd_do_not_flip_flop():
    """The crowd of cases/route-choice, routed again and again on the same density: the waits of a route are those
    of the last one's choices, and without the margin of route_every a part of the crowd switched door at every
    route (4.5 people of 50 at the second) and back; with it nobody switches after the first route."""
    model = Simulation(load_case(CASES / "route-choice")).model
    route, exits = model.solver.routing[0], model.solver.boundary.at(0.0)
    mass, heading = model.state.density * model.domain.area, route._heading(exits)
    choices = []
    for t in range(1, 5):
        assert route.route(float(t), model.state.density, exits)
        choices.append(route.choice[heading].copy())
    assert 0.1 * mass.sum() < mass[choices[0] == 1].sum() < 0.9 * mass.sum()
    for before, after in zip(choices, choices[1:]):
        assert mass[before != after].sum() == 0.0


def test_part_of_the_crowd_takes_the_far_wide_exit():
    """cases/route-choice (a 0.8 m door near the crowd, a 2.4 m one 12 m away, both 1.9 persons/(m s)): with
    shortest paths everybody queues at the near door; with the route choice a part walks to the far one and
    the room empties sooner, every invariant kept."""
    runs = {route: Simulation(load_case(CASES / "route-choice", [f'velocity.route="{route}"'])).run(None, quiet=True)
            for route in ("shortest", "congestion")}
    short, routed = (runs[r].summary for r in ("shortest", "congestion"))
    assert short["evacuated_by_exit"]["far"] == 0.0
    assert 0.1 * routed["evacuated"] < routed["evacuated_by_exit"]["far"] < 0.9 * routed["evacuated"]
    assert routed["evacuation_time"] < 0.8 * short["evacuation_time"]
    for summary in (short, routed):
        assert summary["max_mass_error"] < 1e-12 and summary["min_density_ever"] >= 0
        assert summary["max_density_ever"] <= 5.4 * (1 + 1e-12) and summary["min_pressure_ever"] >= 0
        assert summary["max_complementarity"] < 1e-10
    assert routed["timing"]["route"] > 0 and "route" not in short["timing"]


def summary(case, *overrides):
    """The summary of a run of this shipped case with these overrides."""
    return Simulation(load_case(CASES / case, list(overrides))).run(None, quiet=True).summary


def test_with_two_queues_the_route_choice_beats_shortest_paths():
    """cases/route-queues (100 people between a 0.8 m and a 1.6 m door, both 1.9 persons/(m s)), on its mesh:
    shortest paths split the crowd in halves and the narrow door's half queues for 35.1 s; the route choice sends
    about a third of the crowd there (the narrow door's share of the capacity) and the room empties in 25.6 s."""
    short, routed = summary("route-queues", 'velocity.route="shortest"'), summary("route-queues")
    assert abs(short["evacuated_by_exit"]["narrow"] - short["evacuated_by_exit"]["wide"]) < 0.02 * short["evacuated"]
    assert 0.28 * routed["evacuated"] < routed["evacuated_by_exit"]["narrow"] < 0.4 * routed["evacuated"]
    assert routed["evacuation_time"] < 0.8 * short["evacuation_time"]
    assert routed["max_mass_error"] < 1e-12 and routed["min_pressure_ever"] >= 0
    assert routed["max_density_ever"] <= 5.4 * (1 + 1e-12) and routed["max_complementarity"] < 1e-10


@pytest.mark.slow
def test_the_evacuation_time_of_two_queues_converges():
    """cases/route-queues under mesh refinement (refine 0, 1, 2) and with route_every halved twice (on refine 0
    and 1): the differences shrink, to below 1 % (docs/model.md, "Route choice", has the sequences), and the
    route choice stays at least a fifth shorter than shortest paths on every mesh."""
    def converges(times):
        steps = np.abs(np.diff(times))
        assert steps[1] < 0.5 * steps[0] and steps[1] < 0.01 * times[-1], times

    for refine in (0, 1):
        converges([summary("route-queues", f"mesh.refine={refine}", f"velocity.route_every={every}")
                   ["evacuation_time"] for every in (1.0, 0.5, 0.25)])
    routed = []
    for refine in (0, 1, 2):
        routed.append(summary("route-queues", f"mesh.refine={refine}")["evacuation_time"])
        short = summary("route-queues", f"mesh.refine={refine}", 'velocity.route="shortest"')["evacuation_time"]
        assert routed[-1] < 0.8 * short, (refine, routed, short)
    converges(routed)
