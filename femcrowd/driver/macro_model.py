"""The macro model as the driver runs it: its state and solver, its diagnostics table, its frames."""


import logging

import numpy as np

from ..errors import InputError
from ..linalg.vectors import dot
from ..macro import MacroSolver, MacroState
from ..macro.diagnostics import invariants, population_invariants
from ..macro.solver import MacroStep
from ..macro.transport import LWR_TRANSPORTS
from .checkpoint import parts, restore_parts
from .measurements import MacroMeasurements
from .model import SOURCE_COLUMNS, Evacuation, landing
from .output import triangle_frame
from .populations import initial_densities
from .recorder import Column
from .remaining import Regions
from .scene import Scene, check_transport_cfl
from .sources import macro_inflow

log = logging.getLogger("femcrowd")

#: what a step may lose to round-off (docs/model.md, "What every run shows"): the relative mass error, the
#: complementarity p (1 - rho) over max(1, max p), a density below zero (over rho_max)
INVARIANT_TOL = 1e-8


def broken_invariants(row: dict, rho_max: float) -> str:
    """The invariants a row of history.csv breaks beyond INVARIANT_TOL, as text ("" if none)."""
    broken = []
    if row["mass_error"] > INVARIANT_TOL:
        broken.append(f"mass + evacuated - supplied = {row['mass_error']:.1e} of the supplied mass")
    if row["complementarity"] > INVARIANT_TOL * max(1.0, row["max_pressure"]):
        broken.append(f"complementarity p (1 - rho) = {row['complementarity']:.1e}")
    if row["min_density"] < -INVARIANT_TOL * rho_max:
        broken.append(f"density {row['min_density']:.3g} < 0")
    return "; ".join(broken)


def macro_columns(exit_names) -> list:
    """history.csv columns of a macro run and the summary entries made of them."""
    return [
        Column("time", (("final_time", "last"),)),
        Column("dt"),
        Column("mass", (("initial_mass", "first"), ("final_mass", "last"))),
        Column("evacuated", (("evacuated", "last"),)),
        Column("max_density", (("max_density_ever", "max"),)),
        Column("saturated_area"),
        Column("max_pressure", (("max_pressure_ever", "max"),)),
        Column("active_set_iterations", (("active_set_iterations.mean", "mean_positive"),
                                         ("active_set_iterations.max", "max"),
                                         ("active_set_iterations.steps_with_projection", "count_positive"))),
        Column("step_seconds"),
        Column("min_density", (("min_density_ever", "min"),)),
        Column("min_pressure", (("min_pressure_ever", "min"),)),
        Column("complementarity", (("max_complementarity", "max"),)),
        Column("linear_residual", (("max_linear_residual", "max"),)),
        *[Column(f"evacuated_{name}", ((f"evacuated_by_exit.{name}", "last"),)) for name in exit_names],
        Column("mass_error", (("mass_error", "last"), ("max_mass_error", "max")), history=False),
        Column("pressure_unsaturated", (("max_pressure_unsaturated", "max"),), history=False),
        Column("non_finite", (("non_finite_values", "sum"),), history=False),
    ]


def door_columns(doors) -> list:
    """The columns of the doors with a capacity: the flow through each (persons per second) and the mean pressure
    on it (p of its door nodes); the summary keeps, per door, its largest flow and pressure, the steps it spent
    at capacity and its mean flow over them."""
    columns = []
    for door in doors:
        entry = f"doors.{door.name}"
        columns += [Column(f"flow_{door.name}", ((f"{entry}.max_flow", "max"),)),
                    Column(f"door_pressure_{door.name}", ((f"{entry}.max_pressure", "max"),)),
                    Column(f"at_capacity_{door.name}", ((f"{entry}.flow_at_capacity", "mean_finite"),
                                                        (f"{entry}.steps_at_capacity", "count_finite")),
                           history=False)]
    return columns


def population_columns(names) -> list:
    """The per-population columns of a run with several populations: mass_<name> and evacuated_<name> in
    history.csv, and per population in the summary its masses, smallest density and largest mass error."""
    columns = []
    for name in names:
        entry = f"populations.{name}"
        columns += [Column(f"mass_{name}", ((f"{entry}.initial_mass", "first"), (f"{entry}.final_mass", "last"))),
                    Column(f"evacuated_{name}", ((f"{entry}.evacuated", "last"),)),
                    Column(f"min_density_{name}", ((f"{entry}.min_density_ever", "min"),), history=False),
                    Column(f"mass_error_{name}", ((f"{entry}.max_mass_error", "max"),), history=False)]
    return columns


def level_columns(names) -> list:
    """The columns of a building (docs/floors.md): on_<name>, the people on each floor and stair (its physical
    surface group); the summary keeps the most there were on each."""
    return [Column(f"on_{name}", ((f"levels.{name}.most_people", "max"),)) for name in names]


class MacroModel:
    """A MacroState and its MacroSolver for a scene; rows of diagnostics in the user's density unit."""

    stem = "solution"  # the frame series: solution.pvd

    def __init__(self, scene: Scene):
        case, domain = scene.case, scene.domain
        self.scene, self.domain = scene, domain
        self.rho_max = case["model"]["rho_max"]
        self.fields = case["output"]["fields"]
        self.warned = False   # broken invariants are logged once per run
        with scene.timer("assembly"):
            populations = scene.populations
            laws = [p.law for p in populations]
            if case["scheme"]["transport"] not in LWR_TRANSPORTS and not all(law.constant for law in laws):
                raise InputError(case.file, "scheme.transport", case["scheme"]["transport"],
                                 "a speed law needs a transport with the LWR fluxes: use one of "
                                 f"{', '.join(map(repr, LWR_TRANSPORTS))}")
            self.state = MacroState.initial(initial_densities(case, domain), len(domain.exit_names),
                                            [p.name for p in populations])
            self.solver = MacroSolver(domain, scene.boundary, [p.velocity for p in populations],
                                      case["scheme"]["transport"], case["time"]["cfl"], case["time"]["dt"],
                                      case["projection"]["direct_max"], case["projection"]["tol"], laws,
                                      case["time"]["cfl_quantile"])
            exits = scene.boundary.at(0.0)
            if self.solver.needs_projection:
                self.solver.projection(exits)
            schemes = self.solver.transports(self.state, exits)
            check_transport_cfl(case, min(schemes, key=lambda s: s.max_cfl * s.max_dt))
        self.initial_mass = self.inside = self.mass
        self.empty_fraction = case["time"]["empty_fraction"]
        self.columns = macro_columns(domain.exit_names)
        self.doors = scene.boundary.capped
        self.columns += door_columns(self.doors)
        self.several = len(populations) > 1   # per-population columns and arrays only then
        if self.several:
            self.initial_masses = self.state.rho @ domain.area
            self.columns += population_columns(self.state.populations)
        # a building's floors and stairs: their people per row (docs/floors.md)
        self.levels = {name: np.asarray(cells) for name, cells in (domain.mesh.subdomains or {}).items()
                       if domain.z is not None and not name.startswith("gmsh:")}
        self.columns += level_columns(self.levels)
        self.sources = self.measurements = None   # hooks only for the scenes that have them
        if scene.sources:
            self.sources = macro_inflow(case, scene.sources, domain, self.state.populations)
            self.solver.before_step.append(self.sources)
            self.columns += SOURCE_COLUMNS
        if scene.lines or scene.areas:
            self.measurements = MacroMeasurements(scene.lines, scene.areas, domain, self.rho_max)
            self.measurements.attach(self.solver, self.state)
        self.evacuation = Evacuation(case["time"]["stop_when_empty"], bool(domain.exit_group), self.sources,
                                     max((source.end for source in scene.sources), default=-np.inf),
                                     people=self.initial_mass > 0)
        self.regions = Regions(scene, self.state.populations)
        self.regions.warn_trapped(self.state.density * domain.area * self.rho_max)

    @property
    def inflow(self) -> float:
        """Mass that entered through the sources so far (units of rho_max x m^2)."""
        return self.sources.inflow if self.sources is not None else 0.0

    @property
    def empty_mass(self) -> float:
        return self.empty_fraction * (self.initial_mass + self.inflow)

    @property
    def t(self) -> float:
        return self.state.t

    @property
    def mass(self) -> float:
        return dot(self.domain.area, self.state.density)

    @property
    def timers(self) -> dict:
        return self.solver.timers

    def step(self, until: float) -> MacroStep:
        """One step, not beyond `until` nor the next door change; the solver's diagnostics of it. Notes the mass
        inside (the empty check) and the evacuation time (the first time less than empty_mass is inside, nobody
        arriving)."""
        info = self.solver.step(self.state, landing(self.scene.boundary, self.t, until))
        with self.solver.timers("projection"):   # with the state update: a phase, like every second of the step
            self.inside = self.mass
            self.evacuation.after_step(self.t, self.inside, self.empty_mass)
        return info

    def row(self, info: MacroStep | None = None) -> dict:
        """The diagnostics of the current state (info: the step's, None for the initial state)."""
        d = invariants(self.domain, self.state)
        step = (0.0, 0, 0.0, 0.0) if info is None else (info.dt, info.iterations, info.seconds, info.linear_residual)
        r = self.rho_max
        supplied = self.initial_mass + self.inflow
        error = abs(d["mass"] + d["evacuated"] - supplied) / max(supplied, 1e-300)
        by_exit = {f"evacuated_{name}": float(v) * r
                   for name, v in zip(self.domain.exit_names, self.state.evacuated.sum(axis=0))}
        if self.sources is not None:
            by_exit.update(inflow=self.inflow * r, queued=self.sources.queued * r)
        if self.doors:
            by_exit.update(self._door_row(info))
        if self.levels:
            people = self.state.density * self.domain.area * r
            by_exit.update({f"on_{name}": float(people[cells].sum()) for name, cells in self.levels.items()})
        row = {**by_exit, "time": self.state.t, "dt": step[0], "mass": d["mass"] * r,
               "evacuated": d["evacuated"] * r, "max_density": d["max_density"] * r,
               "saturated_area": d["saturated_area"], "max_pressure": d["max_pressure"],
               "active_set_iterations": step[1], "step_seconds": step[2],
               "min_density": d["min_density"] * r, "min_pressure": d["min_pressure"],
               "complementarity": d["complementarity"], "linear_residual": step[3],
               "mass_error": error, "pressure_unsaturated": d["pressure_unsaturated"],
               "non_finite": d["non_finite"], **(self._population_row() if self.several else {})}
        if not self.warned and (broken := broken_invariants(row, r)):
            self.warned = True
            log.warning(f"t = {row['time']:.6g} s: {broken}: this run's figures from then on are not to be trusted "
                        "(please report the case)")
        return row

    def _door_row(self, info) -> dict:
        """flow_<door> (persons per second), door_pressure_<door> of each door with a capacity in the step of
        info, and the step's seconds and people if the door was at capacity (to 1e-9 of it)."""
        row, flows = {}, (info.doors if info is not None else None) or {}
        for door in self.doors:
            flow, pressure = flows.get(door.name, (0.0, 0.0))
            at_capacity = flow >= (1 - 1e-9) * door.capacity * door.width and flow > 0
            row.update({f"flow_{door.name}": flow * self.rho_max, f"door_pressure_{door.name}": pressure,
                        f"at_capacity_{door.name}": flow * self.rho_max if at_capacity else np.nan})
        return row

    def _population_row(self) -> dict:
        """mass_<name>, evacuated_<name> (user unit), min_density_<name>, mass_error_<name> of each population."""
        row, r = {}, self.rho_max
        supplied = self.initial_masses + (self.sources.arrived if self.sources is not None else 0.0)
        for (name, d), m0 in zip(population_invariants(self.domain, self.state).items(), supplied):
            row.update({f"mass_{name}": d["mass"] * r, f"evacuated_{name}": d["evacuated"] * r,
                        f"min_density_{name}": d["min_density"] * r,
                        f"mass_error_{name}": abs(d["mass"] + d["evacuated"] - m0) / max(m0, 1e-300)})
        return row

    def empty(self) -> bool:
        """Has the crowd left (less than time.empty_fraction of it inside), in a scene that stops then?"""
        return self.evacuation.empty(self.t, self.inside, self.empty_mass)

    def frame(self):
        """The cell fields asked for in [output].fields, in user units, on the triangles."""
        data = {}
        if "density" in self.fields:
            data["density"] = self.state.density * self.rho_max
            if self.several:
                data.update({f"density_{name}": rho * self.rho_max
                             for name, rho in zip(self.state.populations, self.state.rho)})
        if "pressure" in self.fields:
            data["pressure"] = self.state.p
        if "velocity" in self.fields:
            data["velocity"] = self.solver.velocity_field(self.state)
        if self.measurements is not None:
            data["max_density"] = self.measurements.max_density
        return triangle_frame(self.domain, data)

    def snapshot(self) -> dict:
        """The state to continue from (a checkpoint): arrays and numbers."""
        st = self.state
        return {"rho": st.rho, "p": st.p, "evacuated": st.evacuated, "t": st.t, "steps": st.steps,
                **({} if st.jump is None else {"jump": st.jump}),
                **parts(evacuation=self.evacuation, sources=self.sources, measure=self.measurements,
                        **{f"route{k}": v for k, v in enumerate(self.solver.routing)})}

    def restore(self, data: dict) -> None:
        """Continue from a snapshot."""
        st = self.state
        st.rho, st.p, st.evacuated = data["rho"].copy(), data["p"].copy(), data["evacuated"].copy()
        st.jump = data["jump"].copy() if "jump" in data else st.jump
        st.t, st.steps = float(data["t"]), int(data["steps"])
        restore_parts(data, evacuation=self.evacuation, sources=self.sources, measure=self.measurements,
                      **{f"route{k}": v for k, v in enumerate(self.solver.routing)})
        self.inside = self.mass

    def open_files(self, directory, resume: bool = False) -> list:
        """Files the model writes itself as the run goes (none: frames and tables are the driver's)."""
        return []

    def summary(self, recorded: dict) -> dict:
        """What the summary adds to the recorder's entries."""
        return {"steps": self.state.steps,
                "remaining_fraction": self.mass / self.initial_mass if self.initial_mass > 0 else 0.0,
                "evacuation_time": self.evacuation.time, "projection_needed": self.solver.needs_projection,
                "remaining": self.regions.remaining(self.t, np.pad(self.state.rho * self.domain.area * self.rho_max,
                                                                   ((0, 0), (0, 1))), self.inside <= self.empty_mass,
                                                    self.empty_mass * self.rho_max)}
