"""The evacuation time against run time, for each transport and step rule, on three meshes (issue 38;
docs/performance.md, "The evacuation time against run time").

Each scene runs `femcrowd evacuation-times` series (femcrowd/studies/evacuation.py, serial): the reference
series gives the converged times t50, t90, t99 and t_all by Richardson's estimate from its three meshes; every
level of every series is then printed with its steps, CPU seconds, each time and its error (%), and the
fastest point (CPU seconds) whose four errors are all within 1 %. Scenes: cases/room; the 1 m bottleneck of
docs/validation.md and the 40 x 30 m hall of benchmarks/peer.py (made there, under benchmarks/.cache/peer), the
paper's model (constant speed) and, for the bottleneck, the variant weidmann-push (explicit LWR fluxes, and
the linearly implicit ones at the median cell's step).

    python benchmarks/frontier.py --scenes room
"""

import argparse
import math
import sys
import tempfile
from pathlib import Path

import peer  # this script's folder is on sys.path: the scenes of the peer benchmark

from femcrowd.studies.evacuation import observed, study
from femcrowd.studies.recommended import PUSHING, WALLS

IMPLICIT = ["scheme.transport=implicit"]
RULE = [*IMPLICIT, "time.cfl_quantile=0.5"]
RECOMMENDED = [f"{k}={v}" for k, v in {**PUSHING, **WALLS}.items()] + ["boundary.capacity={exit = 1.9}"]
#: per scene: its case directory (a function: the peer scenes are made on demand) and its series
#: (label, overrides, cfl values); the first series is the reference
SCENES = {
    "room": (lambda: Path("cases/room"), [("upwind", [], [0.5]), ("implicit, smallest cell", IMPLICIT, [2, 4]),
                                          ("implicit, median cell", RULE, [1, 2, 4])]),
    "bottleneck": (lambda: peer.scene("bottleneck", 90)[0], [
        ("upwind", [], [1]), ("implicit, median cell", RULE, [1, 2, 4])]),
    "bottleneck-recommended": (lambda: peer.scene("bottleneck", 90)[0], [
        ("recommended (LWR)", RECOMMENDED, [1]), ("recommended (LWR)", RECOMMENDED, [0.5]),
        ("recommended, implicit LWR, median cell", RECOMMENDED + RULE, [1, 4])]),
    "hall": (lambda: peer.scene("hall", 100)[0], [("implicit, median cell", RULE, [1]), ("upwind", [], [1])]),
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--levels", type=int, default=3, help="meshes of each series: mesh.refine 0..levels-1")
    args = parser.parse_args()
    for name in args.scenes:
        directory, series = SCENES[name]
        rows = []
        with tempfile.TemporaryDirectory() as tmp:
            for k, (label, overrides, cfls) in enumerate(series):
                found, _, _ = study(directory(), args.levels, Path(tmp) / str(k), overrides, [float(c) for c in cfls],
                                    serial=True)
                rows += [{**r, "label": f"{label}, cfl {r['cfl']:g}"} for r in found]
        times = [key for key in rows[0] if key.startswith("t ")]
        first = [r for r in rows if r["label"] == rows[0]["label"]]
        converged = [observed([r[t] for r in first], [r["h"] for r in first])[2][-1] for t in times]
        print(f"\n{name}: converged ({rows[0]['label']}, Richardson) " + ", ".join(f"{c:.2f}" for c in converged))
        print("| series | level | cells | steps | CPU (s) | " + " | ".join(f"{t}: s (%)" for t in times) + " |")
        print("|---|---:|---:|---:|---:|" + "---:|" * len(times))
        within = []
        for r in rows:
            errors = [100 * (r[t] - c) / c for t, c in zip(times, converged)]
            print(f"| {r['label']} | {r['level']} | {r['cells']} | {r['steps']} | {r['cpu_seconds']:.3g} | "
                  + " | ".join(f"{r[t]:.3f} ({e:+.1f})" for t, e in zip(times, errors)) + " |")
            if all(abs(e) <= 1 for e in errors):   # nan (no converged value) is never within
                within.append(r)
        best = min(within, key=lambda r: r["cpu_seconds"], default=None)
        print("fastest within 1 %: " + (f"{best['label']}, level {best['level']}, {best['cpu_seconds']:.3g} CPU s"
                                        if best else "none") + ("" if all(map(math.isfinite, converged)) else
                                                                " (no converged value for some times)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
