"""A capacity on an interior door with the implicit prediction (macro/transport/capped.py): the cap in the solve
passes exactly c |door| while a queue lasts, at any step; mass per population, bounds and the sweeps of its
active set; and the explicit step's result as the step goes to 0."""

import numpy as np
import pytest

from femcrowd import Simulation, load_case
from femcrowd.macro.diagnostics import invariants
from femcrowd.macro.transport.capped import capped_step
from femcrowd.mesh.floorplan import build_mesh

C = 0.1   # the doors' capacity, below the free flow of the queue behind them
#: a unimodal flow g = r f(r) with f(1) = 0.2 > 0 (its maximum at r* = 0.625): Godunov's flux differs from
#: rho_K f(rho_L), and a saturated queue still moves
UNIMODAL = 'speed_law = "1 - 0.8 * rho"'


def rooms(tmp_path, doors=(1.0,), transport="implicit", cfl=1.0, quantile=0.5, populations=1, end=3.0,
          law='speed_law = "linear"\npush = 0.2'):
    """A (len(doors) + 1) x 1 m channel of rooms, the side x = 0 an exit, an interior door of capacity C across it
    at each x of `doors`; the rooms beyond the first at density 0.9 (in `populations` equal parts), walking to
    the exit with f(rho) = max(1 - rho, 0.2) (a push: a queue at rho = 1 still moves; `law`: the [velocity]
    lines of another)."""
    length = len(doors) + 1
    lines = "".join(f'[[doors]]\nname = "door{k}"\nfrom = [{x}, 0]\nto = [{x}, 1]\n' for k, x in enumerate(doors))
    plan = tmp_path / "plan.toml"
    plan.write_text(f'size = 0.1\n[outer]\npoints = [[0, 0], [{length}, 0], [{length}, 1], [0, 1]]\n'
                    f'[[exits]]\nname = "exit"\nfrom = [0, 0]\nto = [0, 1]\n{lines}')
    mesh = build_mesh(plan)
    density = f"{0.9 / populations} * (x > 1)"
    if populations > 1:
        initial = "".join(f'[populations.p{i}]\ndensity = "{density}"\n' for i in range(populations))
    else:
        initial = f'[initial]\ndensity = "{density}"\n'
    capacity = ", ".join(f"door{k} = {C}" for k in range(len(doors)))
    rule = f"cfl_quantile = {quantile}\n" if quantile else ""
    (tmp_path / "case.toml").write_text(
        f'[mesh]\nfile = "{mesh.name}"\n[boundary]\nexits = ["exit"]\ncapacity = {{ {capacity} }}\n'
        f'[velocity]\ntype = "field"\nux = "-1"\n{law}\n{initial}'
        f'[scheme]\ntransport = "{transport}"\n[time]\nend = {end}\ncfl = {cfl}\n{rule}')
    return Simulation(load_case(tmp_path)).model


@pytest.mark.parametrize("cfl", [1, 8])
@pytest.mark.parametrize("populations", [1, 2])
@pytest.mark.parametrize("transport, law", [("implicit", None), ("implicit-godunov", UNIMODAL)],
                         ids=["implicit", "implicit-godunov"])
def test_an_interior_door_passes_exactly_its_capacity_at_any_implicit_step(tmp_path, cfl, populations, transport,
                                                                           law):
    """The queue behind the door (x > 1) empties at exactly C per second (C x 1 m) while it lasts, the door
    pushes back, at the median cell's cfl 1 and 8, with either implicit transport (implicit-godunov with a
    unimodal law); each population keeps its mass to 1e-13, rho >= 0, rho <= 1 after the projection, p >= 0 and
    p (1 - rho) = 0."""
    model = rooms(tmp_path, transport=transport, cfl=cfl, populations=populations,
                  **({"law": law} if law else {}))
    domain = model.domain
    behind = domain.centroid[:, 0] > 1
    mass0 = model.state.rho @ domain.area
    t, left, flow = [], [], []
    while model.state.t < 2.5:
        info = model.solver.step(model.state)
        t.append(model.state.t)
        left.append(model.state.density[behind] @ domain.area[behind])
        flow.append(info.doors["door0"][0])
        r = invariants(domain, model.state)
        assert r["min_density"] >= 0 and r["max_density"] <= 1 + 1e-9
        assert r["min_pressure"] >= 0 and r["complementarity"] <= 1e-9
        kept = model.state.rho @ domain.area + model.state.evacuated.sum(axis=1)
        assert np.abs(kept - mass0).max() <= 1e-13
    assert np.abs(np.array(left) - (0.9 - C * np.array(t))).max() <= 1e-12
    assert np.abs(np.array(flow) - C).max() <= 1e-12 * C
    assert info.doors["door0"][1] > 0


def test_the_papers_model_takes_the_cap_in_the_solve_too(tmp_path):
    """The paper's model (f = 1) with the implicit prediction and an interior door: its step is the linearly
    implicit one with f = 1 (the backward-Euler matrix), the door passes C, the mass is kept; a measurement line
    on the door counts C t (its facets' flows of the capped solve)."""
    rooms(tmp_path, cfl=4, law="")
    line = [{"name": "door", "from": [1.0, 0.0], "to": [1.0, 1.0]}]
    model = Simulation(load_case(tmp_path, {"measure.lines": line, "time.end": 2.0})).model
    mass0 = model.initial_mass
    while model.state.t < 2.0:
        info = model.solver.step(model.state)
        assert info.doors["door0"][0] == pytest.approx(C, rel=1e-12)
        r = invariants(model.domain, model.state)
        assert abs(r["mass"] + r["evacuated"] - mass0) <= 1e-13 and r["min_density"] >= 0
        assert r["max_density"] <= 1 + 1e-9
    result = Simulation(load_case(tmp_path, {"measure.lines": line, "time.end": 2.0})).run(stop_when_empty=False)
    m = result.measurements
    np.testing.assert_allclose(np.abs(m["door_count"]), C * m["time"], rtol=1e-12, atol=1e-15)


def test_the_prediction_itself_passes_the_capacity(tmp_path):
    """The implicit prediction with the cap in its solve (before the doors' cut and the projection) carries
    exactly C x 1 m x tau across the door when the free solve would carry more, every density >= 0, each
    population's mass with what left the same as before, in at most 3 sweeps (one door: the free solve, the
    capped one, the check)."""
    model = rooms(tmp_path, cfl=8, populations=2)
    solver, state = model.solver, model.state
    exits = solver.boundary.at(0.0)
    schemes = solver.transports(state, exits)
    dt = solver.stable_dt(state)
    predictions, sweeps = capped_step(schemes, state.rho, dt, solver._seen(state, schemes), exits.caps)
    free = [scheme.step(rho, dt, state.density) for scheme, rho in zip(schemes, state.rho)]
    through = np.abs(sum(p.through for p in predictions).sum())
    assert np.abs(sum(p.through for p in free).sum()) > 1.5 * C * dt
    assert through == pytest.approx(C * dt, rel=1e-12) and sweeps <= 3
    for p, rho in zip(predictions, state.rho):
        assert p.rho.min() >= 0
        assert p.rho @ model.domain.area + p.outflow.sum() == pytest.approx(rho @ model.domain.area, rel=1e-14)


def test_a_door_crossed_both_ways_caps_the_net_flow(tmp_path):
    """Two populations crossing the door in opposite directions (a, 0.6 behind the door, towards the exit; b, 0.3
    before it, away from it), cfl 4 on the median cell: once a's queue has formed (12 steps) the net prediction
    of both is exactly C |e| tau on every facet of the door, each crossed both ways (the flow of b is in the
    target of the solve); each population's mass with what left is kept to round-off, rho~ >= 0."""
    rooms(tmp_path, cfl=4, populations=2)   # the same scene with b walking the other way, from before the door
    text = (tmp_path / "case.toml").read_text()
    text = text.replace('p0]\ndensity = "0.45', 'p0]\ndensity = "0.6').replace(
        'p1]\ndensity = "0.45 * (x > 1)"', 'p1]\ndensity = "0.3 * (x < 1) * (x > 0.5)"\nux = "1"')
    (tmp_path / "case.toml").write_text(text)
    model = Simulation(load_case(tmp_path)).model
    solver, state, area = model.solver, model.state, model.domain.area
    for _ in range(12):
        solver.step(state)
    for _ in range(10):
        exits = solver.boundary.at(state.t)
        schemes = solver.transports(state, exits)
        dt = solver.stable_dt(state)
        predictions = capped_step(schemes, state.rho, dt, solver._seen(state, schemes), exits.caps)[0]
        a, b = (p.through for p in predictions)
        assert np.all(a * b < 0)   # every facet crossed both ways
        np.testing.assert_allclose(np.abs(a + b), exits.caps.rate * dt, rtol=1e-12)
        for p, rho in zip(predictions, state.rho):
            assert p.rho.min() >= 0 and p.rho @ area + p.outflow.sum() == pytest.approx(rho @ area, rel=1e-14)
        solver.step(state)


def test_doors_in_a_row_settle_one_sweep_each(tmp_path):
    """Three rooms, two doors of capacity C in a row: each passes C while its queue lasts; the active set settles
    in at most (doors + 2) sweeps (capped.py: each sweep settles the doors one step further down the flow)."""
    model = rooms(tmp_path, doors=(1.0, 2.0), cfl=4, end=2.0)
    solver, state = model.solver, model.state
    most = 0
    while state.t < 1.5:
        exits = solver.boundary.at(state.t)
        schemes = solver.transports(state, exits)
        most = max(most, capped_step(schemes, state.rho, solver.stable_dt(state), solver._seen(state, schemes),
                                     exits.caps)[1])
        info = solver.step(state)
        assert info.doors["door1"][0] == pytest.approx(C, rel=1e-12)
        assert info.doors["door0"][0] <= C * (1 + 1e-12)
    assert 2 <= most <= 4


def test_the_capped_implicit_step_tends_to_the_explicit_one_at_first_order(tmp_path):
    """The same scene and smallest cell's step, explicit (LWR fluxes rho_K f(rho_L), the cut after the step) and
    implicit (the cap in the solve), cfl 1, 1/2, 1/4 of that step: the L1 distance of the densities at t = 1
    halves with the step (first order: ratios 1.6 to 2.4)."""
    distance = []
    for cfl in (1.0, 0.5, 0.25):
        rho = {}
        for transport in ("upwind", "implicit"):
            directory = tmp_path / f"{transport}-{cfl}"
            directory.mkdir()
            model = rooms(directory, transport=transport, cfl=cfl, quantile=0, end=1.0)
            while model.state.t < 1.0 - 1e-12:
                model.solver.step(model.state, 1.0)
            rho[transport] = model.state.density
        distance.append(model.domain.area @ np.abs(rho["implicit"] - rho["upwind"]))
    ratios = np.array(distance[:-1]) / distance[1:]
    assert np.all((ratios > 1.6) & (ratios < 2.4)), (distance, ratios)
