"""The flow of a door flush with a wall under mesh refinement (issue 34 item 2; docs/model.md, "The flow of a
door flush with a wall").

The scene: a 6 m x 6 m room, a 2.4 m exit flush with its wall x = 6 (1.8 < y < 4.2), no door capacity, 30 people
at 2.5 persons/m^2 in 1 < x < 3 across the room (`--crowd all`): 12 in front of the door (population "front",
1.8 < y < 4.2) and 18 in the two wedges beside it (population "wedge"), whose shortest paths all end at a door
post. `--crowd front` / `wedge` keeps one of them; `--crowd block` is a saturated 1 m x 1 m block against the
wall beside the lower post, alone; `--crowd blob` a smooth crowd of 3.2 people in the lower wedge (a Gaussian of
peak 3 persons/m^2 at (2, 0.9)). `--exit wall` makes the whole wall x = 6 the exit (no door post: what drifts
there is the scheme's, not the door's). The settings are the recommended ones of the density model
(femcrowd/studies/recommended.py MACRO at FREE_SPEED: Predtechenskii and Milinskii's law, slip walls, cfl 1);
`--law` replaces the law (a name or an expression in rho; "constant" is the paper's model at the same speed);
`--transport muscl` takes the second-order transport (scheme.transport = "muscl" at time.cfl = 0.5: Godunov's flux
between limited linear reconstructions, SSP-RK2; femcrowd/macro/transport/muscl_lwr.py).

Per level it prints the cells, steps and CPU seconds of the run; the flow J (persons/s while 20 to 80 % of the
crowd are out, femcrowd/studies/validation.py flow); the times at which half of each population is out; the
times at which 50 %, 90 %, 99 % and all but 1e-4 of the whole crowd are out (femcrowd/studies/evacuation.py); and,
while 20 to 80 % are out, the mean saturated area (rho = rho_max), the mean number of unknowns of the projection
per step (its active set) and of cells within 0.5 m of a post where it acts (phi > 0); and the persons who cross
the edge of the door's shadow beside the lower post (the line y = 1.8 from x = 3 to the wall, as the facets
between the cells whose centroid is below it and those above) by the transport and by the projection's pressure.

`--flux` swaps the LWR flux of femcrowd/macro/transport/lwr.py for a prototype, in this process only:
"godunov" (shipped: q_e min(D(rho_K), S(rho_L)), Lebacque 1996), "downstream" (q_e rho_K f(rho_L), the flux of
the laws whose g has several humps), "demand" (q_e D(rho_K): no supply limit, the projection alone keeps
rho <= 1), "sender" (q_e g(rho_K): the upwind flux of the sender's speed). The time step stays that of the
shipped flux; rho <= 1 is the projection's (f(1) > 0 for the laws measured).

`--fan R` swaps the desired direction for a prototype too: within walking distance R of the exit it is the
steepest descent of the harmonic phi (Laplace's equation, phi = 0 on the exit, phi = d where d >= R, no flux at
the walls) instead of the distance d, so that the crowd beside the door spreads over its width instead of
heading for the post. On {d = R} both gradients are normal to the level set, so the direction is continuous.

    python benchmarks/flush_door.py --levels 0,1,2
    python benchmarks/flush_door.py --levels 0,1,2 --flux demand
    python benchmarks/flush_door.py --levels 0,1,2 --law constant
    python benchmarks/flush_door.py --levels 0,1,2 --crowd block
    python benchmarks/flush_door.py --levels 0,1,2,3 --crowd front --exit wall
    python benchmarks/flush_door.py --levels 0,1,2,3 --crowd blob --fan 2.4
    python benchmarks/flush_door.py --levels 0,1,2,3 --crowd front --exit wall --transport muscl
"""

import argparse
import time

import numpy as np
import scipy.sparse.linalg
import skfem
from skfem.models.poisson import laplace

import femcrowd.api as fc
from femcrowd.driver.run import Simulation
from femcrowd.macro.transport.lwr import LWRTransport
from femcrowd.macro.velocity import ExitsVelocity
from femcrowd.studies.evacuation import evacuation_times
from femcrowd.studies.recommended import FREE_SPEED, MACRO
from femcrowd.studies.validation import flow

SIDE, LOW, HIGH = 6.0, 1.8, 4.2     # the room's side, the door's ends on the wall x = SIDE (m)
RHO_MAX, DENSITY = 5.4, 2.5          # persons/m^2
BAND = "(x > 1) * (x < 3)"
FRONT = f"(y > {LOW}) * (y < {HIGH})"
WEDGE = f"((y < {LOW}) + (y > {HIGH}))"
#: the initial density of each population (persons/m^2) per --crowd
CROWDS = {"all": {"wedge": f"{DENSITY} * {BAND} * {WEDGE}", "front": f"{DENSITY} * {BAND} * {FRONT}"},
          "front": {"front": f"{DENSITY} * {BAND} * {FRONT}"},
          "wedge": {"wedge": f"{DENSITY} * {BAND} * {WEDGE}"},
          "block": {"wedge": f"{RHO_MAX} * (x > {SIDE - 1}) * (y > {LOW - 1}) * (y < {LOW})"},
          "blob": {"wedge": "3 * exp(-(x - 2)**2 / 0.4) * exp(-(y - 0.9)**2 / 0.3)"}}
NEAR_POST = 0.5   # m
#: the shares of the whole crowd out whose times are printed: 50 %, 90 %, 99 % and all but time.empty_fraction
SHARES = (0.5, 0.9, 0.99, 1 - 1e-4)
#: the settings of --transport on top of the recommended ones
TRANSPORTS = {"upwind": {}, "muscl": {"scheme.transport": "muscl", "time.cfl": 0.5}}


def prototype(name):
    """What makes the shipped LWRTransport.flows carry the facet flux `name` (module docstring) once a transport is
    built: its non-Godunov branch, or its Godunov branch with the law's supply made infinite (and its demand made
    g, for "sender"); None: the shipped flux. The step is the shipped flux's, computed before."""
    if name == "godunov":
        return None

    def adjust(transport):
        if name == "downstream":
            transport.godunov = False
            return
        transport.law.supply = lambda rho: np.full(np.shape(rho), np.inf)
        if name == "sender":
            transport.law.demand = transport.law.flux
    return adjust


def fanned(radius):
    """ExitsVelocity.cells with the prototype direction of `--fan` (module docstring), one set of exits."""
    shipped = ExitsVelocity.cells

    def cells(self, exits):
        heading = self._heading(exits)
        if heading not in self._cells:
            edges = self._edges(exits, heading)
            d = self.eikonal.solve_each([edges], self._costed(exits, self.cost))[0]
            stiffness = laplace.assemble(skfem.Basis(self.domain.mesh, skfem.ElementTriP1()))
            free = np.isfinite(d) & (d < radius)
            free[np.unique(edges)] = False
            phi = d.copy()
            rhs = -stiffness[free][:, ~free] @ d[~free]
            phi[free] = scipy.sparse.linalg.spsolve(stiffness[free][:, free].tocsc(), rhs)
            self.distance[heading] = phi
            self._cells[heading] = self._down(self.domain.gradient(phi), exits,
                                              phi[self.domain.triangles].mean(axis=1))
        return shipped(self, exits)
    return cells


def measure(scene, level, crowd, law, transport="upwind"):
    """One run: the numbers of the module docstring."""
    settings = {"model": {"rho_max": RHO_MAX}, "mesh": {"refine": level}, "output": {"every": 1000.0},
                "time": {"end": 60.0}, "velocity": {"speed": FREE_SPEED},
                "populations": {name: {"density": density} for name, density in CROWDS[crowd].items()}}
    for key, value in {**MACRO, **TRANSPORTS[transport]}.items():
        table, name = key.split(".")
        settings.setdefault(table, {})[name] = value
    if law is not None:
        settings["velocity"]["speed_law"] = law
    simulation = Simulation(scene.case(**settings))
    domain = simulation.model.solver.domain
    x, y = domain.centroid.T
    near = np.minimum(np.hypot(x - SIDE, y - LOW), np.hypot(x - SIDE, y - HIGH)) < NEAR_POST
    saturated, unknowns, acting = [], [], []
    below = y < LOW
    k0, k1 = domain.f2t
    inner = np.flatnonzero(domain.interior)
    edge = inner[(below[k0[inner]] != below[k1[inner]]) & (domain.midpoint[inner, 0] > 3.0)]
    upward = np.where(below[k0[edge]], 1.0, -1.0)   # f2t[0] -> f2t[1] is upward across the line
    exits = simulation.scene.boundary.at(0.0)
    crossed = {"transport": 0.0, "pressure": 0.0}

    def transported(solver, state, dt):
        crossed["transport"] += upward @ solver.facet_flux(state, dt, edge)

    def record(solver, state, step):
        saturated.append(domain.area[state.rho.sum(axis=0) >= 1 - 1e-9].sum())
        unknowns.append(step.unknowns)
        acting.append(np.count_nonzero(step.flux.phi[: domain.ncells][near] > 0))
        crossed["pressure"] += upward @ step.flux.facet_flux(domain, exits, edge)
    simulation.model.solver.before_step.append(transported)
    simulation.model.solver.after_step.append(record)
    cpu = time.process_time()
    history = simulation.run().history
    cpu = time.process_time() - cpu
    t, out = np.asarray(history["time"]), np.asarray(history["evacuated"])
    total = history["mass"][0]
    window = ((out >= 0.2 * total) & (out <= 0.8 * total))[1:]
    column = (lambda name, what: f"{what}_{name}") if len(CROWDS[crowd]) > 1 else (lambda name, what: what)
    halves = {name: float(np.interp(0.5 * history[column(name, "mass")][0], history[column(name, "evacuated")], t))
              for name in CROWDS[crowd]}
    return {"cells": domain.ncells, "steps": len(t) - 1, "cpu": cpu, "people": total, "flow": flow(t, out, total),
            "t50": halves, "times": evacuation_times(t[1:], out[1:], total, SHARES),
            "saturated": np.mean(np.array(saturated)[window]),
            "unknowns": np.mean(np.array(unknowns)[window]), "near": np.mean(np.array(acting)[window]),
            "near_cells": int(near.sum()), **{k: RHO_MAX * v for k, v in crossed.items()}}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--levels", default="0,1,2", help="the mesh.refine levels, comma-separated")
    parser.add_argument("--crowd", choices=sorted(CROWDS), default="all")
    parser.add_argument("--law", help="the speed law instead of the recommended one (a name or an expression)")
    parser.add_argument("--exit", choices=("door", "wall"), default="door",
                        help="the 2.4 m door flush with the wall x = 6, or that whole wall")
    parser.add_argument("--fan", type=float, default=0.0,
                        help="a harmonic direction within this walking distance of the exit (m; 0: the shipped one)")
    parser.add_argument("--flux", choices=("godunov", "downstream", "demand", "sender"), default="godunov")
    parser.add_argument("--transport", choices=sorted(TRANSPORTS), default="upwind",
                        help="upwind (recommended, cfl 1) or muscl (second order, cfl 0.5)")
    args = parser.parse_args()
    adjust = prototype(args.flux)
    if adjust is not None:
        shipped = LWRTransport.__init__

        def init(self, *args, **kwargs):
            shipped(self, *args, **kwargs)
            adjust(self)
        LWRTransport.__init__ = init
    if args.fan > 0:
        ExitsVelocity.cells = fanned(args.fan)
    plan = {"size": 0.25, "outer": {"points": [[0, 0], [SIDE, 0], [SIDE, SIDE], [0, SIDE]]},
            "exits": [{"name": "exit", "from": [SIDE, LOW if args.exit == "door" else 0.0],
                       "to": [SIDE, HIGH if args.exit == "door" else SIDE]}]}
    scene = fc.Scene(plan)
    print(f"exit {args.exit}, crowd {args.crowd}, law {args.law or MACRO['velocity.speed_law']}, flux {args.flux}, "
          f"fan {args.fan or 'none'}, transport {args.transport}")
    print("level | cells | steps | CPU (s) | flow (persons/s) | t50 by population (s) | t50, t90, t99, all but 1e-4 "
          "(s) | saturated (m^2) | "
          "projection unknowns | near-post cells with phi > 0 | across the shadow's edge: transport, pressure")
    for level in map(int, args.levels.split(",")):
        m = measure(scene, level, args.crowd, args.law, args.transport)
        halves = ", ".join(f"{name} {value:.2f}" for name, value in m["t50"].items())
        times = ", ".join(f"{value:.2f}" for value in m["times"])
        print(f"{level} | {m['cells']} | {m['steps']} | {m['cpu']:.1f} | {m['flow']:.3f} | {halves} | {times} | "
              f"{m['saturated']:.2f} | {m['unknowns']:.0f} | {m['near']:.0f} of {m['near_cells']} | "
              f"{m['transport']:.2f}, {m['pressure']:.2f}", flush=True)


if __name__ == "__main__":
    main()
