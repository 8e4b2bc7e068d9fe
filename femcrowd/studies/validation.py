"""Flow through a bottleneck against its width, for each model and setting of femcrowd, beside the published
experiments (``femcrowd validate``, docs/validation.md).

The scene: a waiting area of 8 m x 6 m, a crowd of 2.5 persons/m^2 on its first 6 m (90 persons), a
corridor 2 m long and w wide (0.5 ... 5 m), its far end the exit: the geometry of the Juelich bottleneck
experiments (Seyfried et al. 2009; Liao et al. 2014). Beyond 2.4 m the scene of 2.4 m is magnified by
w / 2.4 (every length, the crowd's area and the mesh size: 390 persons at 5 m), so that a wide door has a
queue as long (in time) as the 2.4 m one. Desired speed 1.34 m/s (the setting "predtechenskii": its law's
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
from ..driver import Simulation
from ..driver.output import prepare_output_dir
from ..errors import InputError
from ..files import make_directory, replaced, write_text
from ..mesh.floorplan import build_mesh
from ..plot.validation import flows_plot
from ..timer import Stopwatch
from .execute import execute
from .recommended import CARRYING, DISCS, DOOR_CAPACITY, MACRO, PUSH, SPEED, door_capacity

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


def _capacity() -> str:
    """The recommended capacity on the scene's exit, as a --set text."""
    return f"boundary.capacity={{exit={door_capacity(['exit'])['boundary.capacity']['exit']}}}"


SETTINGS = {
    "paper": Setting("macro, constant speed, free exit (the paper's model)", ()),
    "weidmann": Setting("macro, Weidmann's law (f(rho_max) = 0)", ("velocity.speed_law=weidmann",)),
    "pushing": Setting(f"macro, Weidmann's law, push {PUSH:g}", _set(SPEED)),
    "capacity": Setting(f"macro, constant speed, door capacity {DOOR_CAPACITY:g} /(m s)", (_capacity(),)),
    "recommended": Setting(f"macro, Weidmann's law, push {PUSH:g}, door capacity {DOOR_CAPACITY:g} /(m s) "
                           "(recommended)", (*_set(MACRO), _capacity())),
    "predtechenskii": Setting("macro, Predtechenskii-Milinskii law, door capacity of the width (auto)",
                              _set(CARRYING) + ('boundary.capacity={exit="auto"}',)),
    "discs-paper": Setting("discs r = 0.2 m, pushing (the paper's discs)",
                           ("model.type=micro", "micro.radius=0.2"), discs=True),
    "discs": Setting(f"discs r = 0.2 m, Weidmann's law, push {PUSH:g}, decelerating, fluctuation "
                     f"{DISCS['micro.fluctuation']:g} m/s (recommended)",
                     ("model.type=micro", "micro.radius=0.2", *_set(DISCS)), discs=True),
}


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


def flow(times, evacuated, total):
    """Persons per second while the queue lasts: the least-squares slope of evacuated(t) between 20 % and
    80 % of the crowd out; a crowd that clogs before 80 % are out gets its mean flow over the run."""
    window = (evacuated >= 0.2 * total) & (evacuated <= 0.8 * total)
    if evacuated[-1] < 0.8 * total or window.sum() < 2:
        return float(evacuated[-1] / times[-1])
    return float(np.polyfit(times[window], evacuated[window], 1)[0])


def run_task(task: Task) -> dict:
    """One run, no files written: its flow, specific flow, people, cells and wall time."""
    setting = SETTINGS[task.setting]
    overrides = [*setting.overrides, *task.overrides] + ([f"micro.seed={task.seed}"] if setting.discs
                                                          else [f"mesh.refine={task.level}"])
    clock = Stopwatch()
    simulation = Simulation(load_case(task.case_dir, overrides))
    result = simulation.run()
    h = result.history
    people = float(h["count"][0] if "count" in h else h["mass"][0])
    j = flow(h["time"], h["evacuated"], people)
    return {"setting": task.setting, "width": task.width, "level": task.level, "seed": task.seed,
            "cells": result.domain.ncells, "people": people, "evacuated": float(h["evacuated"][-1]),
            "last_out": float(h["time"][-1]), "flow": j, "specific_flow": j / task.width,
            "all_out": bool(h["evacuated"][-1] >= people - 0.5), "wall": clock.seconds,
            "max_overlap_r": float(result.summary.get("max_overlap_r", 0.0))}


def plan(settings, widths, levels: int, seeds: int, root: Path, overrides=()) -> list:
    """The runs of a validation: every setting at every width, on `levels` meshes or `seeds` seeds (overrides:
    --set texts applied to every run, after the setting's own)."""
    unknown = [s for s in settings if s not in SETTINGS]
    if unknown:
        raise InputError("--settings", None, unknown[0], f"unknown setting (settings: {', '.join(SETTINGS)})")
    tasks = []
    for width in widths:
        if not 0.4 < width < 6.0:
            raise InputError("--widths", None, width, "expected widths between 0.4 m and 6 m")
        directory = str(scene(width, root / "scenes"))
        for name in settings:
            runs = [(0, seed) for seed in range(1, seeds + 1)] if SETTINGS[name].discs \
                else [(level, 0) for level in range(levels)]
            load_case(directory, [*SETTINGS[name].overrides, *overrides])   # checked before any run
            tasks += [Task(name, width, level, seed, directory, tuple(overrides), series=f"{name} w = {width:g} m",
                           mesh=f"micro.seed={seed}" if SETTINGS[name].discs else f"mesh.refine={level}")
                      for level, seed in runs]
    return tasks


def summarise(rows) -> list:
    """Per setting and width: the converged specific flow (finest mesh, or mean over the seeds), its change
    between the last two meshes (or the seeds' range) and how many runs let everyone out."""
    table = []
    for name in dict.fromkeys(r["setting"] for r in rows):
        for width in sorted({r["width"] for r in rows if r["setting"] == name}):
            runs = sorted((r for r in rows if r["setting"] == name and r["width"] == width),
                          key=lambda r: (r["level"], r["seed"]))
            values = np.array([r["specific_flow"] for r in runs])
            if SETTINGS[name].discs:
                value, spread = float(values.mean()), f"{values.min():.2f}-{values.max():.2f} over {len(runs)} seeds"
            else:
                value = float(values[-1])
                spread = " / ".join(f"{v:.3f}" for v in values)
                if len(values) > 1:   # the change between the last two meshes; one mesh has none to show
                    spread += f" ({100 * abs(values[-1] - values[-2]) / abs(values[-2]):.1f} %)"
            table.append({"setting": name, "width": width, "specific_flow": value, "runs": spread,
                          "all_out": f"{sum(r['all_out'] for r in runs)}/{len(runs)}",
                          "cells": runs[-1]["cells"], "wall": sum(r["wall"] for r in runs)})
    return table


def experiments() -> list:
    """The published figures of experiments.csv, as dicts (width_m and specific_flow as numbers)."""
    with open(EXPERIMENTS, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r["width_m"] = float(r["width_m"]) if r["width_m"] else None
        r["specific_flow"] = float(r["specific_flow"])
    return rows


def markdown(table) -> str:
    """The table of docs/validation.md."""
    lines = ["| setting | width (m) | specific flow (persons/(m s)) | meshes (change) or seeds | all out |",
             "|---|---|---|---|---|"]
    lines += [f"| {SETTINGS[r['setting']].label} | {r['width']:g} | {r['specific_flow']:.2f} | {r['runs']} | "
              f"{r['all_out']} |" for r in table]
    return "\n".join(lines) + "\n"


def validate(out, settings=tuple(SETTINGS), widths=WIDTHS, levels: int = 3, seeds: int = 5, overrides=(),
             serial=False, scheduler=None, force=False, echo=None, quiet: bool = True) -> tuple:
    """Run the validation into `out`: validation.csv (every run), validation.md (the table), validation.png.
    Returns (table, markdown, out)."""
    root = prepare_output_dir(Path(out), "--out", force)
    tasks = plan(settings, widths, levels, seeds, root, overrides)
    rows = execute(run_task, tasks, serial, scheduler, echo=echo, quiet=quiet)
    with replaced(root / "validation.csv", sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    table = summarise(rows)
    text = markdown(table)
    write_text(root / "validation.md", text, sync=True)
    flows_plot(rows, table, {name: setting.label for name, setting in SETTINGS.items()}, experiments(),
               root / "validation.png")
    return table, text, root
