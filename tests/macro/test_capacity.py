"""Doors with a capacity (mesh/capacity.py, docs/model.md "Doors with a capacity"): the exact queue flow, the
door's complementarity inside the projection, interior doors, and the constrained Riemann problem of the LWR
fluxes (Colombo, Goatin 2007) converging under refinement."""

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.cli import main
from femcrowd.driver.reading import read_frame, read_history, read_pvd
from femcrowd.macro import MacroSolver, MacroState
from femcrowd.macro.diagnostics import invariants
from femcrowd.macro.projection import Projection
from femcrowd.macro.velocity import FieldVelocity
from femcrowd.mesh import Boundary
from femcrowd.mesh.capacity import width_capacity
from femcrowd.mesh.floorplan import build_mesh

from ..support import CASES, unit_square


def steps(model, end):
    """Step a model to `end`; per step: time, evacuated, the doors' (flow, pressure), the state's invariants."""
    rows = []
    while model.state.t < end - 1e-12:
        info = model.solver.step(model.state, end)
        rows.append({"t": model.state.t, "evacuated": model.state.evacuated.sum(), "doors": info.doors,
                     **invariants(model.domain, model.state)})
    return rows


def assert_invariants(rows, mass0, inflow=0.0):
    """mass + evacuated = mass(0) to 1e-10, 0 <= rho <= 1 + 1e-9, p >= 0, p (1 - rho) = 0, at every step."""
    for r in rows:
        assert abs(r["mass"] + r["evacuated"] - mass0 - inflow) <= 1e-10 * mass0
        assert r["min_density"] >= 0 and r["max_density"] <= 1 + 1e-9
        assert r["min_pressure"] >= 0 and r["complementarity"] <= 1e-9 and r["non_finite"] == 0


def test_a_saturated_block_leaves_at_exactly_the_capacity():
    """A saturated block pushed towards an exit of capacity c = 0.4 (free flow 1): while the queue lasts the exit
    passes exactly c per second (evacuated(t) = c t to 1e-10) and pushes back (door pressure > 0); once it is
    gone the door is free (pressure 0) and everyone is out."""
    case = load_case(CASES / "saturated-exit", ["velocity.ux=-1", "boundary.capacity={exit=0.4}", "time.end=3.2"])
    model = Simulation(case).model
    mass0 = model.initial_mass
    rows = steps(model, 3.2)
    assert_invariants(rows, mass0)
    t, out = np.array([r["t"] for r in rows]), np.array([r["evacuated"] for r in rows])
    pressure = np.array([r["doors"]["exit"][1] for r in rows])
    queue = t < 0.9 * mass0 / 0.4
    assert np.abs(out[queue] - 0.4 * t[queue]).max() <= 1e-10 * mass0
    assert pressure[queue].min() > 0
    assert pressure[t > 2.8].max() == 0 and out[-1] == pytest.approx(mass0, rel=1e-3)


def test_a_capacity_never_reached_leaves_the_free_exit(tmp_path):
    """cases/saturated-exit with a capacity above its flow (at most 1.5 per metre): the door nodes never bind
    and the run is the free-exit run (to round-off: the door nodes change the factorisations' order)."""
    free = Simulation(load_case(CASES / "saturated-exit")).run().history
    capped = Simulation(load_case(CASES / "saturated-exit", ["boundary.capacity={exit=10}"])).run().history
    assert len(free["time"]) == len(capped["time"])
    assert np.abs(free["evacuated"] - capped["evacuated"]).max() <= 1e-12
    assert capped["door_pressure_exit"].max() == 0 and capped["flow_exit"].max() < 10


def test_a_full_room_behind_a_capped_door_keeps_every_invariant():
    """The unit square full (rho = 1 everywhere), pushed towards its left side, an exit of capacity 0.3: every
    step has a saturated zone touching a door at capacity, the singular case of the projection's door
    nodes; evacuated = 0.3 t exactly, both complementarities hold."""
    domain = unit_square(16, exits=["left"])
    boundary = Boundary(domain, capacity={"left": 0.3})

    U = FieldVelocity(domain, Expression("-1"), Expression("0.3 * (0.5 - y)"))
    state = MacroState.initial(np.ones((1, domain.ncells)), 1)
    state.jump = np.zeros(len(domain.length))
    solver = MacroSolver(domain, boundary, [U], cfl=0.5)
    rows = []
    while state.t < 1.0:
        info = solver.step(state)
        rows.append({"t": state.t, "evacuated": state.evacuated.sum(), **invariants(domain, state)})
        assert info.doors["left"][1] > 0
    assert_invariants(rows, 1.0)
    t, out = np.array([r["t"] for r in rows]), np.array([r["evacuated"] for r in rows])
    assert np.abs(out - 0.3 * t).max() <= 1e-12


def test_the_door_nodes_solve_their_complementarity_problem():
    """One projection with door capacities, checked against its LCP: w = b + A phi >= 0, phi >= 0, phi w = 0 on
    the cells and on the door nodes (z = s - flux through the door), and the flux through each capped facet at
    most its room s."""
    domain = unit_square(16, exits=["left", "bottom"])
    doors = Boundary(domain, capacity={"left": 0.2}).at(0.0)
    caps = doors.caps
    rng = np.random.default_rng(3)
    rho_tilde = np.where(domain.centroid[:, 0] < 0.4, 1.0 + 0.3 * rng.random(domain.ncells), 0.5)
    room = rng.random(caps.nodes) * caps.rate[caps.node_facet] * 0.01
    flux, info = Projection(domain, doors)(rho_tilde, room)
    A = caps.extend(doors.laplacian())
    phi = np.concatenate([flux.phi, flux.door])
    b = np.concatenate([domain.area * (1 - rho_tilde), room])
    w = b + A @ phi
    scale = np.concatenate([domain.area, domain.area[caps.node_cell]])
    assert phi.min() >= 0 and w.min() >= -1e-10 * scale.max()
    assert np.abs(phi * w).max() <= 1e-12
    through = flux.facet_flux(domain, doors, caps.facets)
    assert np.all(through <= room + 1e-12) and np.isclose(through, room).any()   # some doors at capacity
    assert flux.door.max() > 0
    rho = flux.apply(rho_tilde, domain.area)
    assert rho.max() <= 1 + 1e-9 and rho.min() >= 0


@pytest.mark.parametrize("deficit", [1e-4, 1e-2])
def test_a_closed_saturated_room_with_space_to_spare_is_not_all_saturated(deficit):
    """Issue 34: a room behind an exit at capacity (room s = 0: its door nodes push back like a wall) is a closed
    room of the extended Laplacian. A short step after a long one (the carried phi too large) spread S over the
    whole room, door nodes included, while the mass lacks `deficit` x area to fill it: the pinned cell was left
    with w = sum b > 0 and phi > 0, p (1 - rho) up to 0.7. Both steps must solve the LCP: phi >= 0, w >= 0,
    phi w = 0, 0 <= rho <= 1, the mass kept (the door passes nothing)."""
    domain = unit_square(16, exits=["left"])
    doors = Boundary(domain, capacity={"left": 0.3}).at(0.0)
    caps = doors.caps
    A = caps.extend(doors.laplacian())
    scale = np.concatenate([domain.area, domain.area[caps.node_cell]])
    room = np.zeros(caps.nodes)
    bump = np.where(domain.centroid[:, 0] < 0.5, 1.0, 0.0)
    bump -= domain.area @ bump / domain.area.sum()
    projection = Projection(domain, doors)
    for height in (1.0, 0.1):   # a long step, then a short one
        rho_tilde = 1 + height * bump - deficit
        flux, info = projection(rho_tilde, room)
        phi = np.concatenate([flux.phi, flux.door])
        w = np.concatenate([domain.area * (1 - rho_tilde), room]) + A @ phi
        assert phi.min() >= 0 and w.min() >= -1e-10 * scale.max()
        assert np.abs(phi * w / scale).max() <= 1e-10
        rho = flux.apply(rho_tilde, domain.area)
        assert rho.min() >= 0 and rho.max() <= 1 + 1e-9
        assert abs(domain.area @ rho - domain.area @ rho_tilde) <= 1e-13


def door_plan(tmp_path):
    """A 2 x 1 m channel, the side x = 0 an exit, an interior door across it at x = 1."""
    plan = tmp_path / "plan.toml"
    plan.write_text('size = 0.1\n[outer]\npoints = [[0, 0], [2, 0], [2, 1], [0, 1]]\n'
                    '[[exits]]\nname = "exit"\nfrom = [0, 0]\nto = [0, 1]\n'
                    '[[doors]]\nname = "door"\nfrom = [1, 0]\nto = [1, 1]\n')
    return build_mesh(plan)


@pytest.mark.parametrize("transport", ["upwind", "compressive"])
def test_an_interior_door_passes_exactly_its_capacity(tmp_path, transport):
    """A saturated crowd behind an interior door of capacity 0.3 (a door between two rooms): the room behind it
    empties at exactly 0.3 per second while the queue lasts, the door pushes back, the invariants hold."""
    mesh = door_plan(tmp_path)
    (tmp_path / "case.toml").write_text(
        f'[mesh]\nfile = "{mesh.name}"\n[boundary]\nexits = ["exit"]\ncapacity = {{ door = 0.3 }}\n'
        f'[velocity]\ntype = "field"\nux = "-1"\n[initial]\ndensity = "1.0 * (x > 1)"\n'
        f'[scheme]\ntransport = "{transport}"\n[time]\nend = 3.0\n')
    model = Simulation(load_case(tmp_path)).model
    domain = model.domain
    behind = domain.centroid[:, 0] > 1
    mass0 = model.initial_mass
    behind0 = domain.area[behind] @ model.state.density[behind]
    rows = []
    while model.state.t < 2.5:
        info = model.solver.step(model.state)
        rows.append({"t": model.state.t, "behind": domain.area[behind] @ model.state.density[behind],
                     "flow": info.doors["door"][0], "pressure": info.doors["door"][1],
                     "evacuated": model.state.evacuated.sum(), **invariants(domain, model.state)})
    assert_invariants(rows, mass0)
    t, left = np.array([r["t"] for r in rows]), np.array([r["behind"] for r in rows])
    assert np.abs(left - (behind0 - 0.3 * t)).max() <= 1e-10 * mass0
    assert min(r["pressure"] for r in rows[1:]) > 0
    assert all(r["flow"] == pytest.approx(0.3, rel=1e-12) for r in rows)


def constrained_riemann(x, t, c=0.16, rho=0.4):
    """Exact LWR solution (f = 1 - rho, U0 = (1, 0)) of a corridor [0, 4] with a wall at x = 0 and an exit of
    capacity c < rho (1 - rho) at x = 4 (Colombo, Goatin 2007): the queue rho_q (congested, g(rho_q) = c)
    grows from the exit behind a shock of Rankine-Hugoniot speed (c - g(rho)) / (rho_q - rho) < 0."""
    queue = (1 + np.sqrt(1 - 4 * c)) / 2
    shock = (c - rho * (1 - rho)) / (queue - rho)
    return np.where(x < (1 - rho) * t, 0.0, np.where(x < 4 + shock * t, rho, queue))


def test_the_constrained_riemann_problem_converges_at_first_order():
    """cases/lwr-shock as a constrained Riemann problem: 0.4 everywhere, exit capacity 0.16 per metre. The exit
    passes exactly 0.16 x 0.5 m per second from the first step, and the L1 error at t = 2 falls like h (both
    waves are shocks: Godunov's scheme smears them over a fixed number of cells)."""
    errors = []
    for level in range(3):
        case = load_case(CASES / "lwr-shock", ["initial.density=0.4", "boundary.capacity={exit=0.16}",
                                                "time.end=2", f"mesh.refine={level}"])
        result = Simulation(case).run()
        h = result.history
        assert np.abs(h["evacuated"] - 0.08 * h["time"]).max() <= 1e-12
        exact = result.domain.cell_average(lambda x, y, t: constrained_riemann(x, 2.0), divisions=8)
        errors.append(result.domain.area @ np.abs(result.state.density - exact))
    rates = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(rates > 0.9), (errors, rates)


def test_door_columns_and_summary(tmp_path):
    """flow_<door> and door_pressure_<door> in history.csv; the summary's mean flow at capacity is c x width."""
    case = load_case(CASES / "room", ["boundary.capacity={exit=0.3}", "time.end=20"])
    result = Simulation(case).run(out=tmp_path / "out")
    h, doors = result.history, result.summary["doors"]["exit"]
    assert doors["flow_at_capacity"] == pytest.approx(0.3, rel=1e-12) and doors["steps_at_capacity"] > 100
    assert h["flow_exit"].max() == pytest.approx(0.3, rel=1e-12) and h["door_pressure_exit"].max() > 0
    header = (tmp_path / "out" / "history.csv").read_text().splitlines()[0].split(",")
    assert "flow_exit" in header and "door_pressure_exit" in header and "at_capacity_exit" not in header


def test_a_run_with_a_capped_door_resumes(tmp_path):
    """cases/room with a capped door, stopped at 6 s and continued to 12 s: the history (door flow and pressure
    included) and the last frame (the velocity uses the doors' pressure jumps) of the uninterrupted run."""
    common = ["-q", "--set", "boundary.capacity={exit=0.3}"]

    def run(out, *args):
        result = CliRunner().invoke(main, ["run", str(CASES / "room"), "--out", str(out), *common, *args])
        assert result.exit_code == 0, result.output

    whole, part = tmp_path / "whole", tmp_path / "part"
    run(whole, "--set", "time.end=12")
    run(part, "--set", "time.end=6")
    run(part, "--set", "time.end=12", "--resume")
    a, b = read_history(whole / "history.csv"), read_history(part / "history.csv")
    for column in ("time", "mass", "evacuated", "flow_exit", "door_pressure_exit", "max_pressure"):
        assert np.allclose(a[column], b[column], rtol=1e-9, atol=1e-12), column
    last = [read_frame(d / read_pvd(d / "solution.pvd")[-1][1]).cell_data for d in (whole, part)]
    assert np.allclose(last[0]["velocity"][0], last[1]["velocity"][0], rtol=0, atol=1e-9)


def test_info_estimates_a_case_with_capacities():
    """femcrowd info of cases/bottleneck (a capped exit): the run time is timed on the real run (its capped door),
    which lasts beyond the budget: extrapolated to the crowd out."""
    result = CliRunner().invoke(main, ["info", str(CASES / "bottleneck")])
    assert result.exit_code == 0, result.output
    assert "capacity = {exit = 1.9}" in result.output and "extrapolated to about" in result.output


def test_the_capacity_of_a_width_is_the_published_law():
    """capacity = "auto": 2.08 persons/(m s) up to 1.2 m, 2.57 from 2.4 m (the means of the experiments at 0.8 to
    1.2 m and at 2.4 to 5 m), linear in between."""
    widths = np.array([0.5, 1.0, 1.2, 1.5, 1.8, 2.4, 3.6, 5.0])
    assert np.allclose(width_capacity(widths), [2.08, 2.08, 2.08, 2.2025, 2.325, 2.57, 2.57, 2.57], atol=1e-12)


def test_a_door_with_an_auto_capacity_passes_exactly_the_capacity_of_its_width():
    """A saturated block (5.4 persons/m^2) pushed at 1 m/s towards the exit of cases/saturated-exit (free flow
    5.4 persons/(m s)) with capacity = "auto": while the queue lasts the exit passes exactly width_capacity(w) x w
    persons per second, and every invariant holds."""
    case = load_case(CASES / "saturated-exit", ["model.rho_max=5.4", "initial.density=5.4 * (x < 1)", "velocity.ux=-1",
                                                'boundary.capacity={exit="auto"}', "time.end=0.5"])
    model = Simulation(case).model
    width = model.domain.length[model.domain.groups["exit"]].sum()
    rows = steps(model, 0.5)
    assert_invariants(rows, model.initial_mass)
    t, out = np.array([r["t"] for r in rows]), np.array([r["evacuated"] for r in rows])
    rate = width_capacity(width) / 5.4 * width   # the state's unit is rho_max
    assert np.abs(out - rate * t).max() <= 1e-10 * model.initial_mass


def test_a_capacity_neither_a_number_nor_auto_is_one_line(tmp_path):
    result = CliRunner().invoke(main, ["run", str(CASES / "saturated-exit"), "--set", 'boundary.capacity={exit="fast"}',
                                       "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "boundary.capacity" in result.output and '"auto"' in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "out").exists()
