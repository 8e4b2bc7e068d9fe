"""What a case will do (``femcrowd info``): mesh statistics, the Plan of the run that ``femcrowd run`` checks
(driver/limits.py) and the wall time of ``femcrowd run`` on this machine; nothing written in the case.

The run time is start-up (the process's imports, measured by ``femcrowd info`` itself) + set-up (the
``Simulation`` that info builds, as the run does) + the time loop, timed on a real prefix of the run: the same
model, frames, history, measurements and sources, writing into a temporary directory, for at most
:data:`BUDGET` seconds. A run that ends within the budget is measured whole; a longer one is extrapolated from
the second half of its prefix (seconds per simulated second, the frames apart) to the time the run ends: when
the crowd is out (:func:`clearing_time`: a queue at the exits) or time.end.
"""

import math
import tempfile
from pathlib import Path

import numpy as np

from ..case import Case
from ..mesh.distance import exit_distance
from ..micro.sampling import HEX_PACKING
from ..timer import Stopwatch
from .limits import LimitError
from .run import Simulation

#: seconds of the run's time loop that ``femcrowd info`` times
BUDGET = 1.5
#: the exits of a crowd's queue pass this times width x speed x the largest flux (:func:`_crowd`), for a density
#: and for discs: the pressure pushes a density through a door faster than the desired speed, discs jam
#: (measured on the shipped cases)
QUEUE_CAPACITY = (2.0, 1.0)


class _Spent(Exception):
    """The prefix's budget is spent (raised by the timed step, caught by :func:`time_prefix`)."""


def time_prefix(simulation: Simulation, budget: float = BUDGET) -> dict:
    """Run `simulation` with its files into a temporary directory until the run ends or `budget` seconds have
    passed. Returns the marks before each step (t, wall seconds, output seconds, people out so far in units of
    saturation x m^2), the steps, the frames written, the loop's seconds (opening the files to summary.json) and
    whether the run ended."""
    model, timer = simulation.model, simulation.timer
    step, marks = model.step, []
    clock = Stopwatch()

    def timed_step(until):
        marks.append((model.t, clock.seconds, timer["output"], _departed(model)))
        if clock.seconds > budget:
            raise _Spent
        return step(until)

    model.step = timed_step   # the Controller's one call into the model per step (an instance attribute)
    with tempfile.TemporaryDirectory() as tmp:
        clock = Stopwatch()
        try:
            simulation.run(Path(tmp) / "run")
            ended = True
        except _Spent:
            ended = False
        finally:
            del model.step
        seconds = clock.seconds
    every = simulation.case["output"]["every"]
    return {"marks": np.array(marks).reshape(-1, 4), "steps": len(marks) - (not ended), "t": model.t,
            "ended": ended, "seconds": seconds, "frames": math.floor(model.t / every + 1e-9) + 1}


def _saturation(model) -> float:
    """Discs per m^2 at saturation (their hexagonal packing): the unit of a disc model's crowd here; 1 for a
    density (already in units of rho_max)."""
    if not hasattr(model, "sim"):
        return 1.0
    r = model.sim.r
    return HEX_PACKING / (np.pi * np.mean(r ** 2)) if len(r) else 1.0


def _departed(model) -> float:
    """The people who have left so far, in units of saturation x m^2."""
    if hasattr(model, "sim"):
        arrived = model.sources.inflow if model.sources is not None else 0
        return (model.initial_count + arrived - model.sim.count) / _saturation(model)
    return float(model.state.evacuated.sum())


def _crowd(scene, model, t: float) -> tuple:
    """The crowd of `model` at time t as it heads for the exits open at t: per cell (and per twentieth of each
    source's arrivals to come) the time it reaches the exits, walking the geodesic distance at its desired speed
    (inf: no open exit to reach), and its people (units of saturation x m^2); and the capacity of the exits
    (the sum of QUEUE_CAPACITY x width x speed x the largest flux rho f(rho) of the speed law, or the door's
    capacity)."""
    domain, exits = scene.domain, scene.boundary.at(t)
    node = exit_distance(domain.points, domain.triangles, exits.edges())
    distance = node[domain.triangles].mean(axis=1)
    speed = np.max([np.hypot(*p.velocity.at_points(domain.centroid, t, exits).T) for p in scene.populations], axis=0)
    if hasattr(model, "sim"):
        people = np.bincount(np.maximum(domain.locate(model.sim.q), 0), minlength=domain.ncells) / _saturation(model)
    else:
        people = model.state.density * domain.area
    with np.errstate(divide="ignore", invalid="ignore"):
        ready, mass = [t + distance / speed], [people]
    for source in scene.sources:   # the arrivals to come
        start = max(source.start, t)
        if source.end > start:
            times = np.linspace(start, source.end, 21)
            walk = distance[domain.f2t[0][source.facets]].mean() / max(speed.max(), 1e-300)
            ready.append((times[:-1] + times[1:]) / 2 + walk)
            discs = source.counted and hasattr(model, "sim")   # a rate of discs (driver/sources.py, micro_arrivals)
            rate = source.profile.level / _saturation(model) if discs else \
                source.per_metre / scene.case["model"]["rho_max"] * source.width
            mass.append(np.array([rate * source.profile.amount(a, b) for a, b in zip(times[:-1], times[1:])]))
    ready, mass = np.concatenate(ready), np.concatenate(mass)
    flux = max(float(p.law.flux(p.law.r_star)) for p in scene.populations)
    walking = float(np.median(speed[speed > 0])) if (speed > 0).any() else 0.0
    free = QUEUE_CAPACITY[hasattr(model, "sim")] * walking * flux
    capacity = sum(exits.doors[name].width * min(free, exits.doors[name].capacity) for name in exits.open)
    inside = mass > 0
    return ready[inside], mass[inside], capacity


def run_end(simulation: Simulation, prefix: dict) -> tuple:
    """When the run whose prefix was timed ends, and why: time.end (a run that does not stop when the crowd is
    out, or people with no exit open to reach) or the crowd out: at the outflow of the prefix's last quarter once
    that outflow no longer grows and 5 % of the crowd has left or it is below the queue's (a jam), and not before
    the farthest person has walked out; else as a queue at the exits (:func:`_crowd`)."""
    model, end, t = simulation.model, simulation.case["time"]["end"], prefix["t"]
    if not model.evacuation.stop:
        return end, "time.end"
    ready, mass, capacity = _crowd(simulation.scene, model, t)
    if not len(mass):
        return t, "crowd out"
    if not np.isfinite(ready).all():
        return end, "time.end: people with no open exit"
    marks = prefix["marks"]
    half, late = (marks[min(int(np.searchsorted(marks[:, 1], marks[-1, 1] * f)), len(marks) - 2)] for f in (0.5, 0.75))
    rates = [(b[3] - a[3]) / max(b[0] - a[0], 1e-300) for a, b in ((half, late), (late, marks[-1]))]
    if capacity <= 0:
        return end, "time.end: no exit capacity"
    behind = np.cumsum(mass[np.argsort(ready)][::-1])[::-1]   # the people ready at r_k or later
    queue = float(np.max(np.sort(ready) + behind / capacity))
    # the queue's capacity is an upper bound of the outflow: an outflow seen lower (a jam) ends the run later
    steady = 0 < rates[1] <= 1.2 * rates[0]
    if steady and (marks[-1, 3] >= 0.05 * (marks[-1, 3] + mass.sum()) or t + mass.sum() / rates[1] > queue):
        return _ending(end, max(t + mass.sum() / rates[1], ready.max()), "crowd out at the outflow of the prefix")
    return _ending(end, queue, "crowd out in a queue at the exits")


def _ending(end: float, out: float, why: str) -> tuple:
    return (end, "time.end") if out >= end else (out, why)


def estimate(simulation: Simulation, setup: float, startup: float = 0.0, budget: float = BUDGET) -> dict:
    """The wall time of ``femcrowd run`` of a Simulation just set up in `setup` seconds, in a process that started
    `startup` seconds before (0 in a process that has imported femcrowd already); its parts and what they are
    based on. The Simulation is run (its prefix): use a fresh one for the run itself."""
    every = simulation.case["output"]["every"]
    prefix = time_prefix(simulation, budget)
    t = prefix["t"]
    result = {"startup_seconds": startup, "setup_seconds": setup, "prefix_seconds": prefix["seconds"],
              "prefix_steps": prefix["steps"], "prefix_time": t, "measured": prefix["ended"]}
    if prefix["ended"]:
        loop, steps, stop, basis = prefix["seconds"], prefix["steps"], t, "the whole run"
    else:
        stop, basis = run_end(simulation, prefix)
        loop, steps = _extrapolate(prefix, stop, every)
        result["seconds_to_end"] = startup + setup + _extrapolate(prefix, simulation.case["time"]["end"], every)[0]
    result.update(loop_seconds=loop, steps=steps, end_time=stop, end=basis, seconds=startup + setup + loop)
    if basis.endswith("queue at the exits") and _may_clog(simulation):
        # whether an arch holds is decided by round-off (docs/micro.md): no prefix tells; the estimate is halfway,
        # geometrically, between the crowd out and time.end (a factor apart)
        result.update(seconds=math.sqrt(result["seconds"] * result["seconds_to_end"]), clog=True)
    return result


def _may_clog(simulation: Simulation) -> bool:
    """Discs of the paper's model (a constant desired speed, no fluctuation) clog at narrow doors for good
    (docs/validation.md); a speed law or a fluctuation frees them."""
    case = simulation.case
    return (hasattr(simulation.model, "sim") and case["micro"]["fluctuation"] == 0
            and all(p.law.constant for p in simulation.scene.populations))


def _extrapolate(prefix: dict, stop: float, every: float) -> tuple:
    """The loop's seconds and steps of a run that ends at `stop`: the prefix's, then its second half's seconds
    and steps per simulated second (the output apart), and the output's seconds per frame for the frames to come."""
    marks, t = prefix["marks"], prefix["t"]
    half = min(int(np.searchsorted(marks[:, 1], marks[-1, 1] / 2)), len(marks) - 2)
    span = marks[-1] - marks[half]
    simulated = max(span[0], 1e-300)
    rate = (span[1] - span[2]) / simulated   # wall seconds of steps and rows per simulated second
    frame = marks[-1, 2] / prefix["frames"]    # output seconds per frame (the checkpoint with it)
    frames = math.floor(stop / every + 1e-9) + 1 + (stop % every > 1e-9 * every)
    steps = prefix["steps"] + (len(marks) - 1 - half) / simulated * (stop - t)
    return (prefix["seconds"] + rate * (stop - t) + frame * max(frames - prefix["frames"], 0),
            float(steps))


def case_info(case: Case, startup: float = 0.0, budget: float = BUDGET) -> dict:
    """Resolved configuration, mesh statistics, the run's Plan (driver/limits.py, what `femcrowd run` checks) and
    its run time (:func:`estimate`; `startup`: the seconds of this process before it, 0 for the Python API); a
    case beyond the limits is set up only as far as its Plan allows ("over": why)."""
    info = {"case_file": str(case.file), "config": case.config}
    clock = Stopwatch()
    try:
        simulation = Simulation(case)
    except LimitError as err:
        info.update(plan=err.plan.values, over=str(err))
        if err.plan.scene is not None:
            info["mesh"], info["exits"] = err.plan.scene.domain.statistics(), list(err.plan.scene.domain.exit_group)
        return info
    setup = clock.seconds
    domain = simulation.scene.domain
    info.update(mesh=domain.statistics(), exits=list(domain.exit_group), plan=dict(simulation.plan.values))
    info["estimate"] = estimate(simulation, setup, startup, budget)
    return info
