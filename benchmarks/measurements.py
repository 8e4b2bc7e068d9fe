"""Cost of the measurements ([[measure.lines]], [[measure.areas]]): whole runs as users make them
(`femcrowd run`, default threads), each with its measurements and without, alternating over `--repeat` rounds.
The table gives the medians over the rounds of the wall time, the share of it booked in the "measurements"
phase of summary.json, and the ratio of the wall times with and without.

Scenes: cases/entrance (two lines, one area), with the macro model and with discs; an office (an L-shaped
30 m x 20 m floor with a partition, a column, exits of 1.2 m and 0.9 m, the narrow one closing at 20 s, an
entrance, two populations, Weidmann's law, two counting lines and an area), with both models.

    python benchmarks/measurements.py
    python benchmarks/measurements.py --repeat 5 --only office
"""

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from alternating import median, rounds  # this script's folder is on sys.path

ROOT = Path(__file__).resolve().parents[1]
FEMCROWD = Path(sys.executable).parent / "femcrowd"

OFFICE_PLAN = """size = 0.3
[outer]
points = [[0, 0], [30, 0], [30, 20], [15, 20], [15, 10], [0, 10]]
[[holes]]
points = [[10, 2], [10.2, 2], [10.2, 8], [10, 8]]
[[holes]]
circle = { center = [22, 5], radius = 0.4 }
[[exits]]
name = "exit_a"
from = [30, 4]
to = [30, 5.2]
[[exits]]
name = "exit_b"
from = [20, 20]
to = [20.9, 20]
[[exits]]
name = "entrance"
from = [0, 4]
to = [0, 6]
"""

OFFICE_CASE = """title = "An L-shaped office: two exits, one closing at 20 s, arrivals, two populations"
[mesh]
file = "office.msh"
[boundary]
exits = ["exit_a", "exit_b"]
[boundary.open]
exit_b = [[0, 20]]
[model]
rho_max = 5.4
[velocity]
speed = 1.34
speed_law = "weidmann"
[populations.staff]
density = "2.0 * (x > 1) * (x < 9) * (y > 1) * (y < 9)"
[populations.visitors]
density = "2.0 * (x > 17) * (x < 28) * (y > 12) * (y < 19)"
[micro]
radius = 0.23
[time]
end = 40.0
[[sources]]
boundary = "entrance"
flow = 1.0
start = 0.0
end = 20.0
population = "staff"
[[measure.lines]]
name = "corridor"
from = [15, 0.2]
to = [15, 9.8]
[[measure.lines]]
name = "wing"
from = [15.2, 10]
to = [29.8, 10]
[[measure.areas]]
name = "front_a"
polygon = [[27, 2.5], [30, 2.5], [30, 6.5], [27, 6.5]]
"""


def scenes(tmp: Path) -> dict:
    """{name: (case directory with measurements, the same without, --set options)}."""
    office = tmp / "office"
    office.mkdir()
    (office / "office.toml").write_text(OFFICE_PLAN)
    subprocess.run([FEMCROWD, "mesh", office / "office.toml", "-o", office / "office.msh"], check=True,
                   capture_output=True)
    (office / "case.toml").write_text(OFFICE_CASE)
    entrance = tmp / "entrance"
    entrance.mkdir()
    text = (ROOT / "cases" / "entrance" / "case.toml").read_text()
    (entrance / "case.toml").write_text(text.replace("../../meshes", str(ROOT / "meshes")))
    made = {}
    for name, folder in (("entrance", entrance), ("office", office)):
        bare = tmp / f"{name}-bare"
        bare.mkdir()
        for f in folder.iterdir():
            (bare / f.name).symlink_to(f)
        (bare / "case.toml").unlink()
        (bare / "case.toml").write_text(re.split(r"\n\[\[measure\.", (folder / "case.toml").read_text())[0] + "\n")
        for model in ("macro", "micro"):
            made[f"{name}, {model}"] = (folder, bare, ["--set", f"model.type={model}"])
    return made


def run(case: Path, options, out: Path) -> dict:
    """One whole run: its wall time and its measurements phase (summary.json)."""
    subprocess.run([FEMCROWD, "run", case, "--out", out, "--force", "-q", *options], check=True,
                   capture_output=True)
    timing = json.loads((out / "summary.json").read_text())["timing"]
    return {"wall": timing["wall"], "measurements": timing.get("measurements", 0.0)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the configurations")
    parser.add_argument("--only", choices=["entrance", "office"], help="one scene")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        print("| scene | wall with (median) | measurements phase | share | wall without | with / without |")
        print("|---|---:|---:|---:|---:|---:|")
        for name, (measured, bare, options) in scenes(tmp).items():
            if args.only and not name.startswith(args.only):
                continue
            configs = [("with", measured, options), ("without", bare, options)]
            runs = rounds(configs, args.repeat, lambda case, opts: run(case, opts, tmp / "out"))
            share = np.median([r["measurements"] / r["wall"] for r in runs["with"]])
            with_, without = median(runs["with"], "wall"), median(runs["without"], "wall")
            print(f"| {name} | {with_:.2f} s | {median(runs['with'], 'measurements'):.2f} s | {100 * share:.1f} % | "
                  f"{without:.2f} s | {with_ / without:.2f} |", flush=True)


if __name__ == "__main__":
    main()
