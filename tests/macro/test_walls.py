"""The desired direction at walls (velocity.walls, macro/walls.py; docs/model.md, "Walls"): with "slip" U never
points into a wall and every cell has a path of upwind flows to an exit, so no cell keeps its mass for ever, for
every transport; the paper's direction ("paper") stays as it was."""

import numpy as np
import pytest
import skfem

from femcrowd import Simulation, load_case
from femcrowd.case import Expression
from femcrowd.driver.scene import build_scene
from femcrowd.macro.speed_law import SpeedLaw
from femcrowd.macro.transport import TRANSPORTS, LWRTransport
from femcrowd.macro.velocity import CongestionVelocity, ExitsVelocity
from femcrowd.macro.walls import draining
from femcrowd.mesh import Boundary, Domain
from femcrowd.mesh.domain import load_domain

from ..support import CASES, MESHES

#: obstacles in the unit square (exit: the side x = 1), by the centroids of the triangles they remove
SOLIDS = {
    "column": lambda x, y: (np.abs(x - 0.5) < 0.125) & (np.abs(y - 0.5) < 0.125),   # a square column
    "door-post": lambda x, y: (np.abs(x - 0.5) < 0.0625) & (np.abs(y - 0.5) > 0.125),  # a wall with a doorway
    "wedge": lambda x, y: np.abs(x - 0.5) + np.abs(y - 0.5) < 0.25,   # a diamond: a 90 degree wedge upstream
}


def obstacle(name, n=8) -> Domain:
    """The unit square (a symmetric mesh, n cells per side) without the triangles of SOLIDS[name]; exit x = 1."""
    mesh = skfem.MeshTri.init_sqsymmetric().refined(int(np.log2(n)))
    x, y = mesh.p[:, mesh.t].mean(axis=1)
    mesh = mesh.remove_elements(np.flatnonzero(SOLIDS[name](x, y)))
    return Domain(mesh.with_boundaries({"exit": lambda p: np.isclose(p[0], 1)}), ["exit"])


def into_wall(domain, exits, cells) -> np.ndarray:
    """U_K . n_e on each wall facet e of its cell K."""
    wall = np.flatnonzero(exits.wall)
    return np.einsum("ij,ij->i", cells[domain.f2t[0][wall]], domain.normal[wall])


@pytest.mark.parametrize("name", SOLIDS)
@pytest.mark.parametrize("n", [8, 32])
def test_slip_never_points_into_a_wall_and_every_cell_drains(name, n):
    """The paper's P1 direction points into the obstacle (up to 0.38-1 of the speed); with slip U . n <= 0 on every
    wall facet (to round-off), |U| = speed in every cell, every cell has a path to the exit, and a cell away from
    the walls whose paper direction drains keeps that direction bit for bit."""
    domain = obstacle(name, n)
    exits = Boundary(domain).at(0.0)
    paper = ExitsVelocity(domain, Expression("1.3")).cells(exits)
    cells = ExitsVelocity(domain, Expression("1.3"), walls="slip").cells(exits)
    assert into_wall(domain, exits, paper).max() > 0.3
    assert into_wall(domain, exits, cells).max() <= 1e-12
    assert np.allclose(np.hypot(*cells.T), 1.3, rtol=1e-12)
    assert draining(domain, exits, cells).all()
    at_wall = np.zeros(domain.ncells, bool)
    at_wall[domain.f2t[0][exits.wall]] = True
    kept = ~at_wall & draining(domain, exits, paper)
    assert np.array_equal(cells[kept], paper[kept]) and kept.mean() > 0.5


def test_the_paper_direction_traps_the_crowd_upstream_of_a_wedge():
    """The reason for the fix: at the wedge's tip the paper's direction points into both faces, and the cells
    upstream whose flows lead there have no path to the exit."""
    domain = obstacle("wedge", 8)
    exits = Boundary(domain).at(0.0)
    trapped = ~draining(domain, exits, ExitsVelocity(domain, Expression("1")).cells(exits))
    assert trapped.sum() >= 10 and np.mean(domain.centroid[trapped, 0] < 0.5) > 0.9


@pytest.mark.parametrize("transport", ["upwind", "muscl", "compressive", "implicit", "weidmann"])
def test_no_mass_stays_behind_a_wedge(transport):
    """The prediction of every transport (and the LWR fluxes of Weidmann's law, push 0.2) from a crowd filling the
    room, until t = 5 (2.5 times the longest walk): with slip all but 1e-6 of it leaves; with the paper's direction
    what is in front of the wedge's tip stays for ever (the projection aside, which moves only a saturated crowd)."""
    domain = obstacle("wedge", 8)
    exits = Boundary(domain).at(0.0)
    mass = 0.2 * domain.area.sum()
    left = {}
    for walls in ("paper", "slip"):
        velocity = ExitsVelocity(domain, Expression("1"), walls=walls)
        normal = velocity.normal_on_facets(None, exits)
        if transport == "weidmann":
            scheme = LWRTransport(domain, exits, normal, SpeedLaw("weidmann", 5.4, 0.2))
        else:
            scheme = TRANSPORTS[transport](domain, exits, normal, velocity.potential(exits))
        dt = scheme.max_dt * (10.0 if transport == "implicit" else scheme.max_cfl)
        rho, out = np.full(domain.ncells, 0.2), 0.0
        for _ in range(int(np.ceil(5.0 / dt))):
            step = scheme.step(rho, dt)
            rho, out = step.rho, out + step.outflow.sum()
        left[walls] = rho @ domain.area
        assert abs(left[walls] + out - mass) <= 1e-12
    assert left["slip"] <= 1e-6 * mass < 1e-2 * mass < left["paper"]


@pytest.mark.parametrize("mesh", sorted(p.name for p in MESHES.glob("*.msh")))
def test_every_cell_of_the_shipped_meshes_drains(mesh):
    """The property on every shipped plan with exits, for the shortest route and the route choice on a crowd: every
    cell that reaches an exit through the mesh has a path of upwind flows to one, and none points into a wall."""
    plan = load_domain(MESHES / mesh)
    exits = [g for g, facets in plan.groups.items() if g != "wall" and not g.startswith("entrance")
             and np.all(plan.f2t[1, facets] < 0)]   # not the interior line groups (a building's stair ends)
    if not exits:
        pytest.skip("a plan without exits")
    domain = load_domain(MESHES / mesh, exits)
    exits = Boundary(domain).at(0.0)
    density = 0.5 + 0.5 * np.sin(7 * domain.centroid[:, 0]) * np.cos(5 * domain.centroid[:, 1])
    route = CongestionVelocity(domain, Expression("1"), None, SpeedLaw("linear"), 1.0, walls="slip")
    route.route(0.0, density, exits)
    for velocity in (ExitsVelocity(domain, Expression("1"), walls="slip"), route):
        cells = velocity.cells(exits)
        reach = np.isfinite(velocity.potential(exits)) & (velocity.potential(exits) >= 0)
        assert np.all(draining(domain, exits, cells)[reach])
        assert into_wall(domain, exits, cells).max(initial=0.0) <= 1e-12


def test_in_front_of_the_column_of_room_column_the_paper_direction_traps_two_cells():
    """Issue 34's column (cases/room-column, mesh.refine = 1): with "paper" two cells just in front of the column's
    face (x = 5.6 m) have no path to the exit; with "slip" every cell has one."""
    for walls, trapped in (("paper", 2), ("slip", 0)):
        scene = build_scene(load_case(CASES / "room-column", [f"velocity.walls={walls}", "mesh.refine=1"]))
        exits = scene.boundary.at(0.0)
        cut = ~draining(scene.domain, exits, scene.populations[0].velocity.cells(exits))
        assert cut.sum() == trapped
        assert np.all(np.abs(scene.domain.centroid[cut] - [5.5, 3.0]).max(axis=1) < 0.1)


@pytest.mark.slow
def test_the_column_case_empties_on_a_refined_mesh():
    """cases/room-column on mesh.refine = 1 (7268 triangles, a few minutes): with "slip" everybody leaves and the
    run reports an evacuation time; with "paper" 0.05 persons stay in front of the column until time.end."""
    for walls in ("paper", "slip"):
        case = load_case(CASES / "room-column", [f"velocity.walls={walls}", "mesh.refine=1", "time.end=90"])
        summary = Simulation(case).run().summary
        if walls == "paper":
            assert summary["evacuation_time"] is None and summary["remaining"]["people"] > 0.01
        else:
            assert summary["evacuation_time"] is not None and summary["remaining"]["reason"] == "evacuated"
