"""femcrowd's independent check: a corridor with a narrowing at its exit (``femcrowd validate --scene corridor``,
docs/validation.md "An independent check"). Nothing of femcrowd was calibrated on it.

The experiment: the uni-directional corridor runs of the Hermes experiments (Duesseldorf 2009; Zhang,
Klingsch, Schadschneider, Seyfried 2011): a corridor 8 m long and 1.8 m wide, people entering over its whole
width (b_entrance = 1.8 m) and leaving through a centred opening of b_exit = 0.7, 0.95, 1.2 or 1.8 m in its
end wall; 148 to 220 persons per run. The figures are the rows of femcrowd/studies/experiments.csv of kind
``check``, read from the archive's trajectories: the time from the first person in to the last person out,
and the mean flow persons / that time.

The scene: the same corridor, the people arriving through its entrance at an even rate (a ``[[sources]]``
entry with ``people``, femcrowd/profiles.py) until the run's crowd has come. The inflow of the experiment was
not found; the default is the mean flow of the run without a narrowing (b_exit = 1.8 m), through the same
entrance. Measured per run: the exit flow (the slope of the people out while 20 to 80 % of the crowd are out,
as ``femcrowd validate``), the time the last person leaves (counted from the first arrival), and the mean
density on the 1 m of corridor in front of the exit wall over that same stretch. Each is divided by the
experiment's figure where one was found.
"""

from pathlib import Path

import numpy as np

from ..driver.output import prepare_output_dir
from ..errors import InputError
from ..files import make_directory, write_text
from ..mesh.floorplan import build_mesh
from ..timer import Stopwatch
from .execute import execute
from .validation import (
    Task,
    check_settings,
    converged,
    experiments,
    flow,
    groups,
    label,
    people_of,
    queue,
    scene_tasks,
    simulate,
    write_rows,
)

#: the corridor: length and width (m)
LENGTH, WIDTH = 8.0, 1.8
#: the depth of the measurement area in front of the exit wall (m)
FRONT = 1.0
PLAN = """size = 0.5
[outer]
points = [[0, 0], [{length}, 0], [{length}, {width}], [0, {width}]]
[[exits]]
name = "exit"
from = [{length}, {low}]
to = [{length}, {high}]
size = 0.2
[[exits]]
name = "entrance"
from = [0, {width}]
to = [0, 0]
"""
CASE = """title = "Corridor 1.8 m, exit {exit:g} m: {people:g} persons arriving at {inflow:g} persons/s"
[mesh]
file = "corridor.msh"
[boundary]
exits = ["exit"]
[model]
rho_max = 5.4                 # persons/m^2 (Weidmann 1993)
[velocity]
speed = 1.34                  # m/s, Weidmann's free speed
[time]
end = {end:g}
[output]
every = 10.0
[[sources]]
boundary = "entrance"
people = {people:g}
start = 0.0
end = {arrivals!r}            # an even rate: people / inflow
[[measure.areas]]
name = "front"                # the last {front:g} m of the corridor, in front of the exit wall
polygon = [[{near}, 0], [{length}, 0], [{length}, {width}], [{near}, {width}]]
"""


def runs() -> dict:
    """The experiment's runs of experiments.csv (kind ``check``), by exit width."""
    return {r["width_m"]: r for r in experiments("check")}


def default_inflow() -> float:
    """Persons per second entering: the mean flow of the run whose exit is as wide as the corridor."""
    return runs()[WIDTH]["flow"]


def scene(exit_width: float, people: float, inflow: float, root: Path) -> Path:
    """The case directory of the corridor with this exit (plan, mesh, case.toml), made once under root."""
    directory = Path(root) / f"corridor-{exit_width:g}-{people:g}-{inflow!r}"
    if not (directory / "case.toml").exists():
        make_directory(directory, own=True)
        low, high = (WIDTH - exit_width) / 2, (WIDTH + exit_width) / 2
        write_text(directory / "corridor.toml", PLAN.format(length=LENGTH, width=WIDTH, low=low, high=high))
        build_mesh(directory / "corridor.toml", directory / "corridor.msh")
        arrivals = people / inflow
        write_text(directory / "case.toml", CASE.format(
            exit=exit_width, people=people, inflow=inflow, arrivals=arrivals, end=10 * arrivals + 100,
            front=FRONT, near=LENGTH - FRONT, length=LENGTH, width=WIDTH))
    return directory


def front_density(times, density, evacuated, people) -> float:
    """The time mean of the density in front of the exit while 20 to 80 % of the crowd are out (the stretch of
    the exit flow, ``validation.queue``; trapezoidal, on the steps); nan for fewer than two steps."""
    inside = queue(evacuated, people)
    if inside.sum() < 2:
        return float("nan")
    return float(np.trapezoid(density[inside], times[inside]) / (times[inside][-1] - times[inside][0]))


def run_task(task: Task) -> dict:
    """One run, no files written: exit flow, last person out, density in front of the exit; people entered."""
    clock = Stopwatch()
    result = simulate(task)
    h, m = result.history, result.measurements
    people = runs()[task.width]["persons"]
    entered = people_of(h) + float(h["inflow"][-1])
    out = h["evacuated"]
    # everyone out: less than half a person inside, and the run's own test of an empty scene (time.empty_fraction)
    # passed before time.end, so that it has an evacuation time
    last_out = result.summary["evacuation_time"]
    all_out = bool(out[-1] >= people - 0.5) and last_out is not None
    return {"setting": task.setting, "width": task.width, "level": task.level, "seed": task.seed,
            "cells": result.domain.ncells, "people": people, "entered": entered, "evacuated": float(out[-1]),
            "flow": flow(h["time"], out, people),
            "last_out": float(last_out) if all_out else float("nan"),
            "front_density": front_density(m["time"], m["front_density"], np.interp(m["time"], h["time"], out),
                                           people),
            "all_out": all_out, "wall": clock.seconds}


def checked(settings, widths, inflow) -> float:
    """The persons per second arriving (`inflow`, or default_inflow()), once settings, widths and inflow are
    known good; else the one-line error of the option."""
    check_settings(settings)
    inflow = default_inflow() if inflow is None else inflow
    if not 0 < inflow <= 20:
        raise InputError("--inflow", None, inflow, "expected persons per second in (0, 20]")
    unknown = [w for w in widths if w not in runs()]
    if unknown:
        raise InputError("--widths", None, unknown[0], "not an exit width of the experiment (widths: "
                         f"{', '.join(f'{w:g}' for w in runs())} m)")
    return inflow


def plan(settings, widths, levels: int, seeds: int, root: Path, overrides=(), inflow=None) -> list:
    """The runs of the check: every setting at every exit width of the experiment, on `levels` meshes or
    `seeds` seeds; people arriving at `inflow` persons/s (default: default_inflow())."""
    inflow = checked(settings, widths, inflow)
    tasks = []
    for width in widths:
        directory = scene(width, runs()[width]["persons"], inflow, root / "scenes")
        tasks += scene_tasks(directory, width, settings, levels, seeds, overrides)
    return tasks


#: the measures of a run and the experiment's figure each is divided by
MEASURES = {"flow": "flow", "last_out": "last_out_s", "front_density": "density_front"}


def ratio(value, measured) -> float:
    """value / measured; nan where the experiment's figure was not found (None) or the value is nan."""
    return float("nan") if measured is None else value / measured


def summarise(rows) -> list:
    """Per setting and exit width: each measure converged (finest mesh, or mean over the seeds) with how it was
    reached, and its ratio to the experiment's figure."""
    known = runs()
    table = []
    for name, width, mine in groups(rows):
        row = {"setting": name, "width": width, "all_out": f"{sum(r['all_out'] for r in mine)}/{len(mine)}"}
        for measure, column in MEASURES.items():
            value, spread = converged(name, [r[measure] for r in mine])
            row |= {measure: value, f"{measure}_runs": spread,
                    f"{measure}_ratio": ratio(value, known[width][column])}
        table.append(row)
    return table


def _number(value, digits: int) -> str:
    return "n/a" if np.isnan(value) else f"{value:.{digits}f}"


def markdown(table, overrides=()) -> str:
    """The table of docs/validation.md, "An independent check": the model's figures and their ratios to the
    experiment's (n/a: no figure found; overrides: the study's --set texts, named with each setting)."""
    known = runs()
    lines = ["| setting | exit (m) | exit flow (persons/s) | / experiment | last out (s) | / experiment | "
             "last out: meshes (change) or seeds | density in front (persons/m^2) | / experiment | all out |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in table:
        lines.append(f"| {label(r['setting'], overrides)} | {r['width']:g} | {_number(r['flow'], 2)} | "
                     f"{_number(r['flow_ratio'], 2)} | {_number(r['last_out'], 1)} | "
                     f"{_number(r['last_out_ratio'], 2)} | {r['last_out_runs']} | {_number(r['front_density'], 2)} | "
                     f"{_number(r['front_density_ratio'], 2)} | {r['all_out']} |")
    lines += ["", "experiment: " + "; ".join(
        f"{w:g} m: {e['persons']:g} persons, last out {e['last_out_s']:g} s, mean flow {e['flow']:g} persons/s"
        for w, e in known.items() if any(r["width"] == w for r in table))]
    return "\n".join(lines) + "\n"


def check(out, settings, widths, levels: int = 3, seeds: int = 5, overrides=(), inflow=None, serial=False,
          scheduler=None, force=False, echo=None, quiet: bool = True) -> tuple:
    """Run the check into `out`: corridor.csv (every run), corridor.md (the table). Returns (table, markdown,
    out)."""
    checked(settings, widths, inflow)   # bad options: one line, before the directory is made
    root = prepare_output_dir(Path(out), "--out", force)
    tasks = plan(settings, widths, levels, seeds, root, overrides, inflow)
    rows = execute(run_task, tasks, serial, scheduler, echo=echo, quiet=quiet)
    write_rows(root / "corridor.csv", rows)
    table = summarise(rows)
    text = markdown(table, overrides)
    write_text(root / "corridor.md", text, sync=True)
    return table, text, root
