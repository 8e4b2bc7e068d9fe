"""Speed and specific flow against density in a corridor, for the macro settings of ``femcrowd validate``, beside
the published fundamental diagram each one's speed law follows (``femcrowd validate --diagram``,
docs/validation.md).

The scene is RiMEA test 4's (cases/rimea/test04-fundamental-diagram: a corridor 10 m wide, the crowd uniform
at one density, the mean speed in a 10 m x 10 m area at 5 s, as femcrowd/studies/rimea.py measures it),
on three meshes; the specific flow is the measured density times the measured speed. The published
diagrams: Weidmann (1993) and Predtechenskii and Milinskii (1978), the rows of kind "diagram" of
femcrowd/studies/experiments.csv.
"""

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import shipped
from ..case import load_case
from ..driver import Simulation
from ..driver.output import prepare_output_dir
from ..errors import InputError
from ..files import replaced, write_text
from ..macro.speed_law import PM_AREA, predtechenskii
from ..timer import Stopwatch
from .execute import execute
from .rimea import weidmann_speed
from .validation import SETTINGS, label

#: the corridor of RiMEA test 4
CORRIDOR = shipped.cases("rimea") / "test04-fundamental-diagram"
#: the densities of the crowd, persons/m^2, and the time of the measurement, s (RiMEA test 4)
DENSITIES = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0)
AT = 5.0
#: how far (relative) a converged speed or specific flow may be from the published one
TOLERANCE = 0.15


def predtechenskii_speed(density):
    """Predtechenskii and Milinskii's speed, m/s, at a density in persons/m^2 (D = PM_AREA x density)."""
    return predtechenskii(PM_AREA * np.asarray(density, dtype=float)) / 60.0


#: the published diagrams, speed (m/s) against density (persons/m^2), of the speed laws of the settings
PUBLISHED = {"weidmann": weidmann_speed, "predtechenskii": predtechenskii_speed}


def law(setting: str) -> str:
    """The speed law a setting of femcrowd validate sets ("constant" if none)."""
    laws = [text.split("=", 1)[1] for text in SETTINGS[setting].overrides if text.startswith("velocity.speed_law=")]
    return laws[-1] if laws else "constant"


def settings_with_diagram() -> tuple:
    """The macro settings whose speed law has a published diagram here."""
    return tuple(name for name, s in SETTINGS.items() if not s.discs and law(name) in PUBLISHED)


@dataclass
class DiagramTask:
    """One run: a setting, the crowd's density, a mesh level."""

    setting: str
    density: float
    level: int
    overrides: tuple = ()
    series: str = ""
    mesh: str = ""
    out: str = ""


def run_point(task: DiagramTask) -> dict:
    """One run, no files written: the density and speed in the measurement area at AT."""
    clock = Stopwatch()
    case = load_case(CORRIDOR, [*SETTINGS[task.setting].overrides, *task.overrides,
                                f"initial.density={task.density}", f"mesh.refine={task.level}"])
    m = Simulation(case).run().measurements
    density, speed = (float(np.interp(AT, m["time"], m[f"middle_{what}"])) for what in ("density", "speed"))
    return {"setting": task.setting, "density": task.density, "level": task.level, "measured_density": density,
            "speed": speed, "specific_flow": density * speed, "wall": clock.seconds}


def plan(settings, densities=DENSITIES, levels: int = 3, overrides=()) -> list:
    """The runs: every setting with a published diagram at every density, on `levels` meshes."""
    bad = [s for s in settings if s not in settings_with_diagram()]
    if bad:
        raise InputError("--settings", None, bad[0], "no published diagram for this setting's speed law (settings: "
                         f"{', '.join(settings_with_diagram())})")
    for name in settings:
        load_case(CORRIDOR, [*SETTINGS[name].overrides, *overrides])   # checked before any run
    return [DiagramTask(name, d, level, tuple(overrides), series=f"{name} rho = {d:g} /m^2",
                        mesh=f"mesh.refine={level}") for name in settings for d in densities for level in range(levels)]


def summarise(rows) -> list:
    """Per setting and density: the finest mesh's speed and specific flow, the published ones, their relative
    differences, the change of the speed between the last two meshes, and whether both are within TOLERANCE."""
    table = []
    for name in dict.fromkeys(r["setting"] for r in rows):
        published = PUBLISHED[law(name)]
        for density in sorted({r["density"] for r in rows if r["setting"] == name}):
            runs = sorted((r for r in rows if r["setting"] == name and r["density"] == density),
                          key=lambda r: r["level"])
            last = runs[-1]
            speed = float(published(density))
            errors = (last["speed"] / speed - 1, last["specific_flow"] / (density * speed) - 1)
            change = abs(runs[-1]["speed"] - runs[-2]["speed"]) / runs[-2]["speed"] if len(runs) > 1 else np.nan
            table.append({"setting": name, "density": density, "speed": last["speed"], "published_speed": speed,
                          "specific_flow": last["specific_flow"], "published_flow": density * speed,
                          "speed_error": errors[0], "flow_error": errors[1], "change": change,
                          "within": bool(max(map(abs, errors)) <= TOLERANCE)})
    return table


def _percent(x) -> str:
    return "-" if np.isnan(x) else f"{100 * x:.2f} %"


def markdown(table, overrides=()) -> str:
    """The table of docs/validation.md (overrides: the study's --set texts, named with each setting)."""
    lines = ["| setting | density (persons/m^2) | speed (m/s): femcrowd / published | specific flow (persons/(m s)): "
             "femcrowd / published | difference (speed, flow) | change of the speed, last two meshes | within "
             f"{100 * TOLERANCE:g} % |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {label(r['setting'], overrides)} | {r['density']:g} | {r['speed']:.3f} / "
              f"{r['published_speed']:.3f} | {r['specific_flow']:.3f} / {r['published_flow']:.3f} | "
              f"{100 * r['speed_error']:+.1f} %, {100 * r['flow_error']:+.1f} % | {_percent(r['change'])} | "
              f"{'yes' if r['within'] else 'no'} |" for r in table]
    return "\n".join(lines) + "\n"


def diagram(out, settings=None, densities=DENSITIES, levels: int = 3, overrides=(), serial=False, scheduler=None,
            force=False, echo=None, quiet: bool = True) -> tuple:
    """Run the check into `out`: diagram.csv (every run), diagram.md (the table). Returns (table, markdown, out)."""
    root = prepare_output_dir(Path(out), "--out", force)
    tasks = plan(settings or settings_with_diagram(), densities, levels, overrides)
    rows = execute(run_point, tasks, serial, scheduler, echo=echo, quiet=quiet)
    with replaced(root / "diagram.csv", sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    table = summarise(rows)
    text = markdown(table, overrides)
    write_text(root / "diagram.md", text, sync=True)
    return table, text, root
