"""Flow through a bottleneck against its width, for each model and setting of femcrowd, beside the published
experiments (``femcrowd validate``, docs/validation.md).

The scene: a waiting area of 8 m x 6 m, a crowd of 2.5 persons/m^2 on its first 6 m (90 persons), a
corridor 2 m long and w wide (0.5 ... 5 m), its far end the exit: the geometry of the Juelich bottleneck
experiments (Seyfried et al. 2009; Liao et al. 2014). Beyond 2.4 m the scene of 2.4 m is magnified by
w / 2.4 (every length, the crowd's area and the mesh size: 390 persons at 5 m), so that a wide door has a
queue as long (in time) as the 2.4 m one. Desired speed 1.34 m/s (the setting "recommended": its law's
1.67 m/s), rho_max = 5.4 persons/m^2 (Weidmann 1993). The flow J is the slope of the people out against
time while the queue lasts (from 20 % to 80 % of the crowd out), the specific flow J / w. Every macro
setting runs on three meshes (the plan's mesh and two uniform refinements), the disc settings on five
seeds; the converged value quoted is the finest mesh's, with its change from the mesh before.

The experiments are femcrowd/studies/experiments.csv: each row a published figure, its source, where in
the source and how it was read.
"""

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..case import load_case
from ..case.loading import toml_value
from ..driver import Simulation
from ..driver.output import prepare_output_dir
from ..errors import InputError
from ..files import make_directory, replaced, write_text
from ..mesh.floorplan import build_mesh
from ..plot.validation import flows_plot
from ..timer import Stopwatch
from .execute import execute
from .recommended import (
    DISCS,
    DOOR_CAPACITY,
    FAST,
    FREE_SPEED,
    MACRO,
    PUSH,
    PUSH_CAPACITY,
    PUSHING,
    WEIDMANN_PUSH,
    door_capacity,
)

#: the published figures (source, year, width_m, specific_flow, flow, kind, where, note)
EXPERIMENTS = Path(__file__).with_name("experiments.csv")
#: widths of the bottleneck, m
WIDTHS = (0.5, 0.8, 1.0, 1.2, 1.6, 2.0, 2.4, 3.0, 3.6, 4.4, 5.0)
#: the widest bottleneck of the scene at its own size, m; a wider one is this scene magnified
LARGEST = 2.4
PLAN = """size = {size:g}
[outer]
points = [[0, 0], [{area:g}, 0], [{area:g}, {low}], [{end:g}, {low}], [{end:g}, {high}], [{area:g}, {high}],
          [{area:g}, {height:g}], [0, {height:g}]]
[[exits]]
name = "exit"
from = [{end:g}, {low}]
to = [{end:g}, {high}]
size = {exit_size:g}
"""
CASE = """title = "Bottleneck {width:g} m: a waiting crowd of 2.5 persons/m^2 (femcrowd validate)"
[mesh]
file = "bottleneck.msh"
[boundary]
exits = ["exit"]
[model]
rho_max = 5.4                 # persons/m^2 (Weidmann 1993)
[velocity]
speed = 1.34                  # m/s, Weidmann's free speed
[initial]
density = "2.5 * (x < {crowd:g})"     # persons/m^2
[time]
end = 200.0
[output]
every = 10.0
"""


@dataclass(frozen=True)
class Setting:
    """A model and its settings: a label for tables and plots, the case overrides, and whether it runs on
    three meshes (macro) or five seeds (discs)."""

    label: str
    overrides: tuple
    discs: bool = False


def _set(overrides: dict) -> tuple:
    """Overrides as --set texts."""
    return tuple(f"{key}={value}" for key, value in overrides.items())


def _capacity(capacity=DOOR_CAPACITY) -> str:
    """A capacity on the scene's exit (the recommended one by default), as a --set text."""
    return f"boundary.capacity={{exit={toml_value(door_capacity(['exit'], capacity)['boundary.capacity']['exit'])}}}"


SETTINGS = {
    "paper": Setting("macro, constant speed, free exit (the paper's model)", ()),
    "weidmann": Setting("macro, Weidmann's law (f(rho_max) = 0)", ("velocity.speed_law=weidmann",)),
    "pushing": Setting(f"macro, Weidmann's law, push {PUSH:g}", _set(PUSHING)),
    "capacity": Setting(f"macro, constant speed, door capacity {PUSH_CAPACITY:g} /(m s)", (_capacity(PUSH_CAPACITY),)),
    "weidmann-push": Setting(f"macro, Weidmann's law, push {PUSH:g}, door capacity {PUSH_CAPACITY:g} /(m s) "
                             "(weidmann-push)", (*_set(WEIDMANN_PUSH), _capacity(PUSH_CAPACITY))),
    "recommended": Setting(f"macro, Predtechenskii-Milinskii law at {FREE_SPEED:.2f} m/s, door capacity of the width "
                           "(recommended)", (*_set({**MACRO, "velocity.speed": FREE_SPEED}), _capacity())),
    "fast": Setting(f"macro, Predtechenskii-Milinskii law at {FREE_SPEED:.2f} m/s, door capacity of the width, "
                    "implicit-godunov at cfl 1.5 of the median cell (fast)",
                    (*_set({**FAST, "velocity.speed": FREE_SPEED}), _capacity())),
    "discs-paper": Setting("discs r = 0.2 m, pushing (the paper's discs)",
                           ("model.type=micro", "micro.radius=0.2"), discs=True),
    "discs": Setting(f"discs r = 0.2 m, Weidmann's law, push {PUSH:g}, decelerating, fluctuation "
                     f"{DISCS['micro.fluctuation']:g} m/s (recommended)",
                     ("model.type=micro", "micro.radius=0.2", *_set(DISCS)), discs=True),
}


def label(name: str, overrides=()) -> str:
    """A setting's label in tables and plots, naming the study's --set keys (applied after the setting's own, so
    the label of the setting alone would no longer say what ran)."""
    return SETTINGS[name].label + (f"; --set {' '.join(overrides)}" if overrides else "")


@dataclass
class Task:
    """One run: a setting at a width, on a mesh level (macro) or with a seed (discs)."""

    setting: str
    width: float
    level: int
    seed: int
    case_dir: str
    overrides: tuple = ()
    series: str = ""
    mesh: str = ""
    out: str = ""
    values: dict = field(default_factory=dict)


def scene(width: float, root: Path) -> Path:
    """The case directory of the bottleneck of this width (plan, mesh, case.toml), made once under root."""
    directory = Path(root) / f"bottleneck-{width:g}"
    if not (directory / "case.toml").exists():
        make_directory(directory, own=True)
        s = max(1.0, width / LARGEST)
        write_text(directory / "bottleneck.toml", PLAN.format(
            size=0.25 * s, area=8 * s, end=10 * s, low=3 * s - width / 2, high=3 * s + width / 2, height=6 * s,
            exit_size=0.1 * s))
        build_mesh(directory / "bottleneck.toml", directory / "bottleneck.msh")
        write_text(directory / "case.toml", CASE.format(width=width, crowd=6 * s))
    return directory


def queue(evacuated, total) -> np.ndarray:
    """The steps while the queue lasts: 20 % to 80 % of the crowd out."""
    return (evacuated >= 0.2 * total) & (evacuated <= 0.8 * total)


def flow(times, evacuated, total):
    """Persons per second while the queue lasts: the least-squares slope of evacuated(t) between 20 % and
    80 % of the crowd out; a crowd that clogs before 80 % are out gets its mean flow over the run."""
    window = queue(evacuated, total)
    if evacuated[-1] < 0.8 * total or window.sum() < 2:
        return float(evacuated[-1] / times[-1])
    return float(np.polyfit(times[window], evacuated[window], 1)[0])


def simulate(task: Task):
    """One run of a task, no files written: the setting's keys, the study's --set keys, then the mesh level
    (macro) or the seed (discs). Returns the run's Result."""
    setting = SETTINGS[task.setting]
    overrides = [*setting.overrides, *task.overrides] + ([f"micro.seed={task.seed}"] if setting.discs
                                                          else [f"mesh.refine={task.level}"])
    return Simulation(load_case(task.case_dir, overrides)).run()


def people_of(history) -> float:
    """The crowd of a run at its start: the discs, or the mass."""
    return float(history["count"][0] if "count" in history else history["mass"][0])


def run_task(task: Task) -> dict:
    """One run, no files written: its flow, specific flow, people, cells and wall time."""
    clock = Stopwatch()
    result = simulate(task)
    h = result.history
    people = people_of(h)
    j = flow(h["time"], h["evacuated"], people)
    return {"setting": task.setting, "width": task.width, "level": task.level, "seed": task.seed,
            "cells": result.domain.ncells, "people": people, "evacuated": float(h["evacuated"][-1]),
            "last_out": float(h["time"][-1]), "flow": j, "specific_flow": j / task.width,
            "all_out": bool(h["evacuated"][-1] >= people - 0.5), "wall": clock.seconds,
            "max_overlap_r": float(result.summary.get("max_overlap_r", 0.0))}


def check_settings(settings) -> None:
    """Every name one of SETTINGS, else the one-line error of --settings."""
    unknown = [s for s in settings if s not in SETTINGS]
    if unknown:
        raise InputError("--settings", None, unknown[0], f"unknown setting (settings: {', '.join(SETTINGS)})")


def scene_tasks(directory, width: float, settings, levels: int, seeds: int, overrides=()) -> list:
    """The runs of the settings on one scene's case directory: `levels` meshes (macro) or `seeds` seeds (discs),
    each setting's case checked before any run."""
    tasks = []
    for name in settings:
        discs = SETTINGS[name].discs
        runs = [(0, seed) for seed in range(1, seeds + 1)] if discs else [(level, 0) for level in range(levels)]
        load_case(directory, [*SETTINGS[name].overrides, *overrides])   # checked before any run
        tasks += [Task(name, width, level, seed, str(directory), tuple(overrides), series=f"{name} w = {width:g} m",
                       mesh=f"micro.seed={seed}" if discs else f"mesh.refine={level}")
                  for level, seed in runs]
    return tasks


def plan(settings, widths, levels: int, seeds: int, root: Path, overrides=()) -> list:
    """The runs of a validation: every setting at every width, on `levels` meshes or `seeds` seeds (overrides:
    --set texts applied to every run, after the setting's own)."""
    check_settings(settings)
    tasks = []
    for width in widths:
        if not 0.4 < width < 6.0:
            raise InputError("--widths", None, width, "expected widths between 0.4 m and 6 m")
        tasks += scene_tasks(scene(width, root / "scenes"), width, settings, levels, seeds, overrides)
    return tasks


def converged(name: str, values) -> tuple:
    """A setting's value over its runs (in level or seed order) and how it was reached: the finest mesh's, with
    every mesh's value and the change between the last two, or the mean over the seeds with their range."""
    values = np.asarray(values, float)
    if SETTINGS[name].discs:
        return float(values.mean()), f"{values.min():.2f}-{values.max():.2f} over {len(values)} seeds"
    spread = " / ".join(f"{v:.3f}" for v in values)
    if len(values) > 1:   # the change between the last two meshes; one mesh has none to show
        spread += f" ({100 * abs(values[-1] - values[-2]) / abs(values[-2]):.1f} %)"
    return float(values[-1]), spread


def groups(rows) -> list:
    """The runs per setting and width, in the order of the rows, each sorted by level and seed:
    [(setting, width, runs)]."""
    return [(name, width, sorted((r for r in rows if r["setting"] == name and r["width"] == width),
                                 key=lambda r: (r["level"], r["seed"])))
            for name in dict.fromkeys(r["setting"] for r in rows)
            for width in sorted({r["width"] for r in rows if r["setting"] == name})]


def summarise(rows) -> list:
    """Per setting and width: the converged specific flow (finest mesh, or mean over the seeds), its change
    between the last two meshes (or the seeds' range) and how many runs let everyone out."""
    table = []
    for name, width, runs in groups(rows):
        value, spread = converged(name, [r["specific_flow"] for r in runs])
        table.append({"setting": name, "width": width, "specific_flow": value, "runs": spread,
                      "all_out": f"{sum(r['all_out'] for r in runs)}/{len(runs)}",
                      "cells": runs[-1]["cells"], "wall": sum(r["wall"] for r in runs)})
    return table


def write_rows(path: Path, rows) -> None:
    """Every run of a study as a CSV file (written whole or not at all)."""
    with replaced(path, sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


#: the columns of experiments.csv that hold numbers (empty: not published, or not found)
NUMBERS = ("width_m", "specific_flow", "flow", "density", "speed", "persons", "last_out_s", "density_front")


def experiments(kind: str | None = None) -> list:
    """The published figures of experiments.csv (those of one `kind` if given: measured, guideline, fit,
    diagram (fundamental-diagram figures: density, speed), check, the figures of femcrowd's independent
    check, or stair, speeds up and down stairs: docs/floors.md), as dicts; the numbers as floats, None where
    empty."""
    with open(EXPERIMENTS, newline="") as f:
        rows = [r for r in csv.DictReader(f) if kind is None or r["kind"] == kind]
    for r in rows:
        r.update({key: float(r[key]) if r[key] else None for key in NUMBERS})
    return rows


def markdown(table, overrides=()) -> str:
    """The table of docs/validation.md (overrides: the study's --set texts, named with each setting)."""
    lines = ["| setting | width (m) | specific flow (persons/(m s)) | meshes (change) or seeds | all out |",
             "|---|---|---|---|---|"]
    lines += [f"| {label(r['setting'], overrides)} | {r['width']:g} | {r['specific_flow']:.2f} | {r['runs']} | "
              f"{r['all_out']} |" for r in table]
    return "\n".join(lines) + "\n"


def validate(out, settings=tuple(SETTINGS), widths=WIDTHS, levels: int = 3, seeds: int = 5, overrides=(),
             serial=False, scheduler=None, force=False, echo=None, quiet: bool = True) -> tuple:
    """Run the validation into `out`: validation.csv (every run), validation.md (the table), validation.png.
    Returns (table, markdown, out)."""
    root = prepare_output_dir(Path(out), "--out", force)
    tasks = plan(settings, widths, levels, seeds, root, overrides)
    rows = execute(run_task, tasks, serial, scheduler, echo=echo, quiet=quiet)
    write_rows(root / "validation.csv", rows)
    table = summarise(rows)
    text = markdown(table, overrides)
    write_text(root / "validation.md", text, sync=True)
    flows_plot(rows, table, {name: label(name, overrides) for name in SETTINGS}, experiments(),
               root / "validation.png")
    return table, text, root
