"""The disc model as the driver runs it: discs of the scene, catching-up steps, diagnostics table, frames.

The discs come from ``[micro].positions`` (CSV with x, y, r) or are sampled without overlap
from ``[initial]`` (count from ``[micro].count``, else from the density at the hexagonal
packing density); walls and obstacles are the wall facets of the mesh, exits its exit
facets (a closed exit is a wall, but it does not close on a disc in its doorway: docs/micro.md,
"Doors that close"). Time step: ``time.dt``, else tau = cfl * r_min / max|U| (a disc moves at
most cfl radii per step). On a building (docs/floors.md, "Discs on stairs") the discs live in the layout of its
pieces' charts (micro/surface.py): walls, exits, desired velocities, point location and output go through it.
"""

import logging
from types import SimpleNamespace

import numpy as np

from ..errors import InputError, RunFailed
from ..macro.velocity import CongestionVelocity, ExitsVelocity
from ..micro import MicroSimulation
from ..micro.clearance import Clearance
from ..micro.contacts import WallSet
from ..micro.density import disc_density
from ..micro.scheme import Uncovered
from ..micro.strategies import DesiredVelocity, View
from ..micro.surface import Atlas, StairTooShort
from ..timer import Timer
from .checkpoint import parts, restore_parts
from .macro_model import level_columns
from .measurements import MicroMeasurements
from .model import SOURCE_COLUMNS, Evacuation, landing
from .output import disc_frame
from .populations import disc_populations, initial_densities
from .recorder import Column
from .remaining import Regions
from .scene import Scene, initial_discs
from .sources import micro_arrivals
from .trajectories import TrajectoryFile

log = logging.getLogger("femcrowd")

MICRO_COLUMNS = [
    Column("time", (("final_time", "last"),)),
    Column("dt"),
    Column("count", (("initial_count", "first"), ("final_count", "last"))),
    Column("evacuated", (("evacuated", "last"),)),
    Column("contacts"),
    Column("max_overlap", (("max_overlap", "max"),)),
    Column("overlap_r", (("max_overlap_r", "max"),)),
    Column("gap", (("max_gap", "max"),)),
    Column("change", (("max_change", "max"),)),
    Column("solver_iterations", (("solver_iterations.mean", "mean_over_steps"), ("solver_iterations.max", "max"))),
    Column("step_seconds"),
    Column("kkt", (("max_kkt", "max"),)),
    Column("outside", (("discs_outside", "max"),), history=False),
]


def population_columns(names) -> list:
    """count_<name>, evacuated_<name> of a run with several populations (and their summary entries)."""
    return [column for name in names for column in (
        Column(f"count_{name}", ((f"populations.{name}.initial_count", "first"),
                                 (f"populations.{name}.final_count", "last"))),
        Column(f"evacuated_{name}", ((f"populations.{name}.evacuated", "last"),)))]


class MicroModel:
    """A MicroSimulation of the scene's discs; rows of diagnostics, disc frames."""

    stem = "discs"  # the frame series: discs.pvd

    def __init__(self, scene: Scene):
        case, domain, boundary = scene.case, scene.domain, scene.boundary
        self.case, self.domain, self.boundary = case, domain, boundary
        if boundary.capped:
            log.warning("%s: the disc model has no door capacity: [boundary.capacity] is not used (how many discs "
                        "pass a door follows from the discs)", case.file)
        with scene.timer("discs"):
            # a building: the discs in the layout of its pieces' charts (micro/surface.py)
            try:
                surface = self.surface = Atlas(domain) if domain.z is not None else None
            except ValueError as err:   # pieces the discs cannot walk (two stairs or two floors sharing an edge)
                raise InputError(case.file, "mesh.file", case["mesh"]["file"], str(err)) from None
            self.locate = domain.locate if surface is None else surface.locate
            exits = self.exits = boundary.at(0.0)
            rho = initial_densities(case, domain)
            q, r = initial_discs(case, domain, exits, rho.sum(axis=0) if len(rho) > 1 else None, surface)
            populations = scene.populations
            if surface is None:
                speed = max(np.hypot(*p.velocity.at_points(domain.centroid, 0.0, exits).T).max() for p in populations)
            else:   # the speed on the surface: the length of the lift of U, that of U in the charts
                speed = max(np.hypot(*surface.to_chart(p.velocity.cells(exits), surface.piece_of_cell).T).max()
                            for p in populations)
            self.r_min = float(r.min()) if len(r) else float(np.min(case["micro"]["radius"]))
            tau = case["time"]["dt"]
            if tau is None:
                tau = case["time"]["cfl"] * self.r_min / speed if speed > 0 else case["output"]["every"]
            self.tau = tau
            spec = case["micro"]
            self.population = disc_populations(case, domain, rho, q, self.locate)
            self.names = [p.name for p in populations]
            radius = max(float(np.max(spec["radius"])), float(r.max()) if len(r) else 0.0)
            desired = DesiredVelocity([self._desired(p.velocity, radius) for p in populations],
                                      self.population, [p.law for p in populations], spec["strategy"],
                                      View(spec["view_distance"], spec["view_angle"]))
            self.sim = MicroSimulation(q, r, *self._segments(exits), desired, tau, method=spec["method"],
                                       fluctuation=spec["fluctuation"], seed=spec["seed"], surface=surface)
            self.doorways, self.held = {}, set()   # exit name -> WallSet of its facets; the exits held open
            desired.sim = self.sim
            self.routing = [p.velocity for p in populations if isinstance(p.velocity, CongestionVelocity)]
            self.desired, self.initial_count = desired, len(q)
            self.columns = list(MICRO_COLUMNS)
            self.levels = [] if surface is None else surface.names   # a building's floors and stairs
            self.columns += level_columns(self.levels)
            if len(populations) > 1:
                self.columns += population_columns(self.names)
                self.initial_counts = np.bincount(self.population, minlength=len(populations))
            self.sources = self.measurements = self.trajectories = None   # only for the scenes that have them
            if scene.sources:
                self.sources = micro_arrivals(case, scene.sources, domain, case["micro"]["radius"],
                                            exits.segments("wall"), case["micro"]["seed"], self.names)
                self.columns += SOURCE_COLUMNS
            if scene.lines or scene.areas:
                self.measurements = MicroMeasurements(scene.lines, scene.areas, case["model"]["rho_max"])
                self.measurements.start(self.sim)
            self.trajectory_rate = case["output"]["trajectory_rate"]
        self.evacuation = Evacuation(case["time"]["stop_when_empty"], bool(domain.exit_group), self.sources,
                                     max((source.end for source in scene.sources), default=-np.inf),
                                     people=self.initial_count > 0)
        self.regions = Regions(scene, self.names)
        self.regions.warn_trapped(np.bincount(self.locate(q) + 1, minlength=domain.ncells + 1)[1:])
        self.last = None   # the last step's StepInfo (positions, velocities, pressures of its discs)
        self.timers = Timer()

    def _desired(self, velocity, radius):
        """U0(q, t) of a population's desired velocity at the discs: in plan, or on a building the plan U of the
        cell holding each disc in the chart of its piece; with ``micro.walls = "clearance"`` the direction of the
        walking distance of disc centres of this radius (micro/clearance.py)."""
        if self.case["micro"]["walls"] == "clearance":
            velocity = self._cleared(velocity, radius)
        if self.surface is None:
            return lambda xy, t: velocity.at_points(xy, t, self.boundary.at(t))
        return lambda X, t: self.surface.velocity(X, velocity.cells(self.boundary.at(t)))

    def _cleared(self, velocity, radius):
        """A population's desired velocity for disc centres kept `radius` from the walls: that of the exits (not the
        route choice, whose cost is the crowd's, nor a given field)."""
        if type(velocity) is not ExitsVelocity:
            log.warning("%s: micro.walls = 'clearance' applies to velocity.type = 'exits' without route choice: "
                        "this population's direction is kept", self.case.file)
            return velocity
        centroids = self.domain.centroid if self.surface is None else \
            self.surface.points[self.surface.triangles].mean(axis=1)
        return Clearance(velocity, centroids, lambda doors: self._segments(doors)[0], radius)

    def _segments(self, doors):
        """The walls and exits of the discs for these doors (on a building in the layout, with the walls seen
        across the folds)."""
        if self.surface is None:
            return doors.segments("wall"), doors.segments("exit")
        return self.surface.segments(doors.wall, True), self.surface.segments(doors.exit, False)

    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def state(self) -> MicroSimulation:
        """The discs: positions q, radii r, velocities u of those still inside."""
        return self.sim

    def step(self, until: float):
        """One step, not beyond `until` nor the next door change (a shorter one lands exactly on it); its
        StepInfo."""
        sim = self.sim
        until = landing(self.boundary, sim.t, until)
        exits = self.boundary.at(sim.t)   # the doors the discs head for
        doors = self._doors(exits)
        if doors is not self.exits:   # a door closed or opened: walls and exits follow
            sim.set_boundary(*self._segments(doors))
            self.exits = doors
        sim.tau = min(self.tau, until - sim.t)
        if any(velocity.due(sim.t, exits) for velocity in self.routing):
            with self.timers("route"):   # the route choice, re-solved when it is due
                density = disc_density(self.domain.centroid, sim.q, sim.r)
                for velocity in self.routing:
                    velocity.route(sim.t, density, exits)
        with self.timers("step"):
            if self.sources is not None:
                q_in, r_in, population = self.sources(sim.t, sim.tau, sim.q, sim.r)
                sim.add(q_in, r_in)
                self.desired.population = self.population = np.concatenate([self.population, population])
            before, ids = sim.q, sim.ids   # the discs before the step (the step makes new arrays)
            try:
                info = sim.step()
            except (Uncovered, StairTooShort) as err:
                self._fail(str(err))
            self.outside = self._escaped(info)
        if until - sim.t < 1e-12 * max(1.0, until):
            sim.t = until
        sim.tau = self.tau
        if self.measurements is not None:
            with self.timers("measurements"):
                self.measurements.record(before, ids, sim, info)
        if self.trajectories is not None:
            with self.timers("trajectories"):
                self.trajectories.step(sim.t, info.dt, info.ids, info.q, info.u)
        self.last = info
        self.evacuation.after_step(sim.t, info.count, 0)
        return info

    def _escaped(self, info) -> int:
        """The discs outside the domain after a step: none, since a disc leaves through an exit only (and is then
        removed); one that crossed a wall is an error naming the step's perturbation or its time step."""
        outside = np.flatnonzero(self.locate(info.q) < 0)
        if not len(outside):
            return 0
        where = info.q[outside[:1]] if self.surface is None else self.surface.xyz(info.q[outside[:1]])
        self._fail(f"{len(outside)} disc(s) left the domain through a wall in the step to t = {info.time:.6g} s (tau "
                   f"= {info.dt:.3g} s), the first to ({', '.join(f'{v:.6g}' for v in where[0])}): a disc leaves "
                   "through an exit only")

    def _fail(self, what):
        """A step gone wrong: RunFailed naming the discs' perturbation (micro.fluctuation) or else their time step."""
        spec, time = self.case["micro"], self.case["time"]
        key = ("micro.fluctuation", spec["fluctuation"]) if spec["fluctuation"] > 0 else \
            ("time.dt", time["dt"]) if time["dt"] is not None else ("time.cfl", time["cfl"])
        raise RunFailed(self.case.file, *key, f"{what}; a smaller perturbation or time step keeps the discs in")

    def _doors(self, scheduled):
        """The walls and exits of the discs: the `scheduled` doors, but an exit due to close stays open while a
        disc stands in its doorway (overlaps its facets) and closes at the first step at which it is clear: a
        door does not close on a person, and no disc overlaps a wall (docs/micro.md, "Doors that close")."""
        closing = [name for name in self.exits.open if name not in scheduled.open]
        held = [name for name in closing if self._occupied(name)]
        for name in closing:
            if name in held and name not in self.held:
                log.warning("exit %r is to close at t = %.6g s while discs stand in its doorway: it stays open "
                            "until they have left it", name, self.sim.t)
            elif name not in held:
                log.info("exit %r closed at t = %.6g s", name, self.sim.t)
        self.held = set(held)
        return self.boundary.opening([*scheduled.open, *held]) if held else scheduled

    def _occupied(self, name) -> bool:
        """Does a disc overlap the facets of the exit `name`?"""
        if name not in self.doorways:
            if self.surface is None:
                self.doorways[name] = WallSet(self.boundary.segments(name))
            else:
                facets = np.zeros(len(self.domain.length), bool)
                facets[next(door for door in self.boundary.doors if door.name == name).facets] = True
                self.doorways[name] = WallSet(self.surface.segments(facets, False))
        return bool(np.any(self.doorways[name].distance(self.sim.q) < self.sim.r))

    def row(self, info=None) -> dict:
        """The diagnostics of a step (info: its StepInfo; None: the initial discs)."""
        sim = self.sim
        outside = self.outside if info is not None else int(np.count_nonzero(self.locate(sim.q) < 0))
        extra = self._population_row() if len(self.names) > 1 else {}
        if self.levels:
            extra.update({f"on_{name}": int(n) for name, n in zip(self.levels, self.surface.counts(sim.q))})
        if self.sources is not None:
            extra.update(inflow=self.sources.inflow, queued=self.sources.queued)
        if info is None:
            return {"time": sim.t, "dt": 0.0, "count": sim.count, "evacuated": 0, "contacts": 0,
                    "max_overlap": 0.0, "overlap_r": 0.0, "gap": 0.0, "change": 0.0, "solver_iterations": 0,
                    "step_seconds": 0.0, "kkt": 0.0, "outside": outside, **extra}
        return {**info.row(), "time": sim.t, "outside": outside, **extra}

    def _population_row(self) -> dict:
        """count_<name> and evacuated_<name> of each population (arrivals counted in their population)."""
        count = np.bincount(self.population[self.sim.ids], minlength=len(self.names))
        arrived = np.bincount(self.population[self.initial_count:], minlength=len(self.names))
        return {k: int(v) for name, c, c0 in zip(self.names, count, self.initial_counts + arrived)
                for k, v in ((f"count_{name}", c), (f"evacuated_{name}", c0 - c))}

    def empty(self) -> bool:
        """Has every disc left (and nobody arrives any more), in a scene that stops then?"""
        return self.evacuation.empty(self.sim.t, self.sim.count, 0)

    def open_files(self, directory, resume: bool = False) -> list:
        """The trajectories of the discs (PedPy's Juelich text format) and the walkable area (WKT); a resumed
        run keeps the frames written before its checkpoint."""
        self.trajectories = TrajectoryFile(directory, self.trajectory_rate, self.domain,
                                           self.resumed_frame if resume else None,
                                           self.surface)
        if not resume:
            self.trajectories.start(self.sim.t, self.sim.ids, self.sim.q)
        return [self.trajectories]

    def frame(self):
        """The discs with radius, velocity and pressure (t = 0: desired velocities, no contact forces yet)."""
        extra = {"population": self.population[self.sim.ids]} if len(self.names) > 1 else {}
        if self.last is None:
            sim = self.sim
            u = sim.desired_velocity() if sim.count else np.zeros((0, 2))
            q, r, pressure = sim.q, sim.r, np.zeros(sim.count)
        else:
            q, r, u, pressure = self.last.q, self.last.r, self.last.u, self.last.pressure
        if self.surface is not None:   # the discs at their (x, y, z), their velocities along their pieces
            q, u = self.surface.xyz(q), self.surface.velocity3d(q, u)
        return disc_frame(q, r, u, pressure, extra)

    def snapshot(self) -> dict:
        """The discs to continue from (a checkpoint), with their contact network and perturbations: a resumed
        run continues bit for bit."""
        sim, last = self.sim, self.last
        pressure = last.pressure if last is not None else np.zeros(sim.count)
        return {**sim.state(), "pressure": pressure, "exits_open": np.array(self.exits.open, dtype=str),
                "population": self.population,
                **parts(evacuation=self.evacuation, sources=self.sources, measure=self.measurements,
                        **{f"route{k}": v for k, v in enumerate(self.routing)}),
                **({} if self.trajectories is None else {"trajectory_frame": self.trajectories.frame})}

    def restore(self, data: dict) -> None:
        """Continue from a snapshot."""
        sim = self.sim
        exits = self.boundary.opening(data["exits_open"].tolist())   # the walls of the checkpoint's contact network
        if exits is not self.exits:
            sim.set_boundary(*self._segments(exits))
            self.exits = exits
        self.held = set(exits.open) - set(self.boundary.at(float(data["t"])).open)
        sim.restore(data)
        self.desired.population = self.population = data["population"].copy()
        restore_parts(data, evacuation=self.evacuation, sources=self.sources, measure=self.measurements,
                      **{f"route{k}": v for k, v in enumerate(self.routing)})
        self.resumed_frame = int(data["trajectory_frame"]) if "trajectory_frame" in data else None
        self.last = SimpleNamespace(q=sim.q, r=sim.r, u=sim.u, pressure=data["pressure"].copy())

    def summary(self, recorded: dict) -> dict:
        """What the summary adds to the recorder's entries."""
        sim, cells = self.sim, self.domain.ncells + 1
        cell = self.locate(sim.q)
        where = np.where(cell < 0, cells - 1, cell)   # the last column: discs outside every cell
        people = np.bincount(self.population[sim.ids] * cells + where, minlength=len(self.names) * cells)
        return {"steps": sim.nstep, "tau": self.tau, "evacuation_time": self.evacuation.time,
                "remaining": self.regions.remaining(sim.t, people.reshape(len(self.names), cells), sim.count == 0)}
