"""What a run will take, known before it starts, and the limits past which it is refused (docs/tools.md,
"Limits"): the desired speeds, the triangles of the refined mesh, the discs to sample (or read) and the walls'
sample points of their contacts, the time step, the steps, the frames, the memory and the disk.

A :class:`Plan` is filled in stage by stage as a case is set up (``Simulation``): the mesh's size before it is
refined, the speeds, the discs before they are sampled or read, the steps and frames once the model is built;
each stage checks what it adds and raises :class:`LimitError` (one line naming the key responsible, exit 2) at
the first limit passed, before anything is allocated for it and before the output directory is touched.
``femcrowd info`` prints the same plan; ``femcrowd run --no-limits`` (``limits=None``) only fills it in.
"""

import math
import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..macro.velocity import FieldVelocity
from ..micro.contacts import WALL_SPACING
from ..micro.sampling import target_count
from .populations import initial_densities
from .scene import read_positions


@dataclass(frozen=True)
class Limits:
    """The most a run may plan: frames, steps, a fraction of this machine's physical memory, bytes of files."""

    frames: float = 1e5
    steps: float = 1e8
    memory: float = 0.8
    disk: float = 50e9
    speed: float = 100.0   # m/s: a desired speed or micro.fluctuation (people run at up to 10 m/s)


LIMITS = Limits()

# What a run costs, measured on cases/room (mesh.refine = 3 and 4) and cases/narrow-door-micro (micro.radius =
# 0.01 and 0.005): the peak resident memory grew by 1.2 kB per triangle and 6.3 kB per disc; a frame takes 44
# bytes per triangle or per disc, history.csv 10 bytes per value, trajectories.txt 30 bytes per disc and frame.
MEMORY_BASE = 150e6          # Python, numpy, scipy, the set-up
MEMORY_PER_TRIANGLE = 1.5e3
MEMORY_PER_DISC = 8e3
MEMORY_PER_VALUE = 32        # a number kept in the Recorder's rows: a list item and its float object
# The discs' contacts with the walls come from points sampled along them every r_max (the largest radius; at
# least 1 nm; micro/contacts.py, WallSet): 72-134 bytes a point measured (peak resident memory, radii 1e-3 and
# 1e-6 m on cases/narrow-door-micro's walls).
MEMORY_PER_WALL_POINT = 150
FRAME_BYTES = 50             # per triangle (macro) or disc (micro)
VALUE_BYTES = 12             # per value of a history.csv row
TRAJECTORY_BYTES = 35        # per disc and trajectory frame

# The scales against which the key responsible for too many steps is chosen: steps = end / (c h / v), with c
# the step as a fraction of the CFL-1 step (time.cfl, or time.dt over the CFL-1 step), h the length a person
# crosses in a CFL-1 step (the mesh's cells; a disc's radius) and v the fastest desired speed; the key whose
# factor is furthest beyond its scale is named.
SCALES = {"end": 3600.0, "every": 0.1, "cfl": 0.5, "length": 0.01, "speed": 2.0}

HINT = 'docs/tools.md, "Limits"; femcrowd run --no-limits runs it anyway'


class LimitError(InputError):
    """A run that plans more than a limit allows; ``plan``: the Plan so far (what ``femcrowd info`` prints)."""

    def __init__(self, plan, key, value, message):
        super().__init__(plan.case.file, key, value, message)
        self.plan = plan


def physical_memory() -> float:
    """Bytes of physical memory of this machine (POSIX sysconf; inf where it is not known)."""
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return math.inf


def _whole(x: float):
    """x rounded up to an int while a float counts exactly (beyond: the float)."""
    return math.ceil(x) if x < 2 ** 53 else x


class Plan:
    """What a run of `case` will take (``values``: triangles, discs, dt, steps, frames, memory and disk in bytes),
    filled in by the stages of its set-up, each checked against `limits` (None: not checked)."""

    def __init__(self, case, limits: Limits | None = LIMITS):
        self.case, self.limits = case, limits
        self.values, self.scene = {}, None

    def mesh(self, triangles: int) -> None:
        """The mesh's triangles once refined (load_domain calls this before refining): its memory."""
        self.values["triangles"] = triangles
        refine = self.case["mesh"]["refine"]
        key = ("mesh.refine", refine) if refine else ("mesh.file", self.case["mesh"]["file"])
        over = self._memory()
        if over:
            self._refuse(key, f"{triangles:.3g} triangles: {over}")

    def speeds(self, scene) -> None:
        """The fastest desired speed at t = 0 (cell centroids, every population) and, for discs, the standard
        deviation of their perturbation (micro.fluctuation), each at most the limit on speeds."""
        self.scene, case, limit = scene, self.case, self.limits
        if limit is None:
            return
        sigma = case["micro"]["fluctuation"]
        if case["model"]["type"] == "micro" and sigma > limit.speed:
            self._refuse(("micro.fluctuation", sigma), f"a perturbation of {sigma:.3g} m/s per component, more than "
                         f"the limit of {limit.speed:g} m/s")
        speed, key = _fastest(case, scene, 0.0)
        if speed > limit.speed:
            self._refuse(key, f"a desired speed of up to {speed:.3g} m/s, more than the limit of {limit.speed:g} m/s")

    def discs(self, scene) -> None:
        """The discs a micro case samples or reads (before they are): their memory, with that of the points
        sampled along the walls for their contacts (one every r_max)."""
        self.scene, case = scene, self.case
        spec = case["micro"]
        if case["model"]["type"] != "micro":
            return
        domain = scene.domain
        walls = float(domain.length[~domain.interior].sum())
        if spec["positions"] is not None:
            _, r, _ = read_positions(case)
            count, radius, key = len(r), float(r.max()), ("micro.positions", spec["positions"])
        elif spec["count"] is not None:
            count, radius, key = spec["count"], float(np.max(spec["radius"])), ("micro.count", spec["count"])
        else:   # what sample_discs draws from the density (driver/scene.py, initial_discs), in its phase
            with scene.timer("discs"):
                rho = initial_densities(case, domain).sum(axis=0)
                count = target_count(lambda xy: rho[np.maximum(domain.locate(xy), 0)], domain.points,
                                     domain.triangles, spec["radius"])
            radius, key = float(np.max(spec["radius"])), ("micro.radius", spec["radius"])
        self.values["discs"] = count
        self.values["wall_points"] = points = walls / max(radius, WALL_SPACING)
        if key[0] == "micro.count" and points * MEMORY_PER_WALL_POINT > count * MEMORY_PER_DISC:
            key = ("micro.radius", spec["radius"])   # the walls' points cost more than the discs
        over = self._memory()
        if over:
            self._refuse(key, f"{count:.3g} discs of radius up to {radius:.3g} m ({points:.3g} points along the "
                         f"{walls:.3g} m of walls for their contacts): {over}")

    def run(self, model) -> None:
        """The time step, steps, frames, memory and files of the run to time.end (fewer when the crowd leaves
        first), all of them, then checked; model: the MacroModel or MicroModel just built."""
        case, v = self.case, self.values
        end, every = case["time"]["end"], case["output"]["every"]
        micro = case["model"]["type"] == "micro"
        v["dt"] = dt = model.tau if micro else model.solver.stable_dt(model.state)
        ratio = end / every   # frame k at k x every, the last one at the end
        v["frames"] = frames = math.floor(ratio + 1e-9) + 1 if ratio < 2 ** 53 else ratio
        v["steps"] = steps = max(_whole(end / dt), frames - 1)   # a step lands on every frame time
        if micro:
            v["discs"] = model.initial_count   # as sampled (or read)
        over = self._memory(steps * len(model.columns) * MEMORY_PER_VALUE)   # the Recorder keeps every row
        rate = case["output"]["trajectory_rate"]
        parts = {"frames": frames * (v["discs"] if micro else v["triangles"]) * FRAME_BYTES,
                 "history": steps * sum(c.history for c in model.columns) * VALUE_BYTES,
                 "trajectories": v["discs"] * end * rate * TRAJECTORY_BYTES if micro else 0.0}
        v["disk"] = disk = sum(parts.values())
        limit = self.limits
        if limit is None:
            return
        if frames > limit.frames:
            self._refuse(self._frames_key(), f"{frames:.3g} frames from t = 0 to {end:g} s (time.end), one every "
                         f"{every:g} s (output.every), more than the limit of {limit.frames:.3g}")
        if steps > limit.steps:
            self._refuse(self.steps_key(model), f"{steps:.3g} steps of dt = {dt:.3g} s to t = {end:g} s (time.end), "
                         f"more than the limit of {limit.steps:.3g}")
        if over:
            self._refuse(self.steps_key(model), f"{steps:.3g} steps of history: {over}")
        if disk > limit.disk:
            most = max(parts, key=parts.get)
            key = {"frames": self._frames_key, "history": lambda: self.steps_key(model),
                   "trajectories": lambda: ("output.trajectory_rate", rate)}[most]()
            self._refuse(key, f"about {disk / 1e9:.3g} GB of files (mostly {most}: {frames:.3g} frames, "
                         f"{steps:.3g} steps), more than the limit of {limit.disk / 1e9:.3g} GB")

    def _memory(self, extra: float = 0.0) -> str:
        """The memory of what is planned so far (+ extra bytes); why it is beyond the limit, or ''."""
        v = self.values
        v["memory"] = (MEMORY_BASE + v.get("triangles", 0) * MEMORY_PER_TRIANGLE
                       + v.get("discs", 0) * MEMORY_PER_DISC + v.get("wall_points", 0) * MEMORY_PER_WALL_POINT + extra)
        if self.limits is None or v["memory"] <= self.limits.memory * physical_memory():
            return ""
        return (f"about {v['memory'] / 1e9:.3g} GB of memory, more than {self.limits.memory:.0%} of this "
                f"machine's {physical_memory() / 1e9:.3g} GB")

    def _refuse(self, key, message):
        raise LimitError(self, *key, f"{message} ({HINT})")

    def _frames_key(self):
        """output.every, unless time.end is further beyond its scale."""
        end, every = self.case["time"]["end"], self.case["output"]["every"]
        if end / SCALES["end"] > SCALES["every"] / every:
            return "time.end", end
        return "output.every", every

    def steps_key(self, model) -> tuple:
        """(key, value) responsible for the steps of the model at its time: time.end, time.cfl or time.dt, the
        desired speed (velocity.speed, ux, uy or a population's), the mesh or the discs' radius."""
        case, t, scene = self.case, model.t, self.scene
        end, dt = case["time"]["end"], self.values["dt"]
        speed, speed_key = _fastest(case, scene, t)
        factors = {("time.end", end): end / SCALES["end"]}
        if case["model"]["type"] == "micro":
            dt1 = model.r_min / speed if speed > 0 else math.inf
            length_key = ("micro.radius", case["micro"]["radius"])
        else:
            dt = model.solver.stable_dt(model.state)
            dt1 = min(s.max_dt for s in model.solver.transports(model.state, scene.boundary.at(t)))
            refine = case["mesh"]["refine"]
            length_key = ("mesh.refine", refine) if refine else ("mesh.file", case["mesh"]["file"])
        if math.isfinite(dt1) and speed > 0:
            fixed = case["time"]["dt"]
            step_key = ("time.dt", fixed) if fixed is not None else ("time.cfl", case["time"]["cfl"])
            factors[step_key] = SCALES["cfl"] / (dt / dt1)
            factors[speed_key] = speed / SCALES["speed"]
            factors[length_key] = SCALES["length"] / (dt1 * speed)
        return max(factors, key=factors.get)


def _fastest(case, scene, t) -> tuple:
    """The fastest desired speed at time t (cell centroids) and the (key, value) that sets it."""
    exits = scene.boundary.at(t)
    best = (0.0, ("velocity.speed", case["velocity"]["speed"]))
    for population in scene.populations:
        velocity = population.velocity
        field = isinstance(velocity, FieldVelocity)
        with np.errstate(all="ignore"):
            u = np.nan_to_num(velocity.at_centroids(t, exits), nan=np.inf)
        name = ("ux", "uy")[int(np.abs(u[:, 1]).max() > np.abs(u[:, 0]).max())] if field else "speed"
        own = case["populations"].get(population.name, {})
        key = f"populations.{population.name}.{name}" if own.get(name) is not None else f"velocity.{name}"
        speed = float(np.hypot(u[:, 0], u[:, 1]).max())
        if speed > best[0]:
            best = (speed, (key, own.get(name) if own.get(name) is not None else case["velocity"][name]))
    return best
