"""The evacuation time against run time, for each transport and step rule, on three meshes (issue 38;
docs/performance.md, "The evacuation time against run time").

Each scene runs `femcrowd evacuation-times` series (femcrowd/studies/evacuation.py, serial): the reference
series gives the converged times t50, t90, t99 and t_all by Richardson's estimate from its three meshes; every
level of every series is then printed with its steps, CPU seconds, each time and its error (%), and the
fastest point (CPU seconds) whose four errors and door flow error (persons/s while 20 to 80 % are out) are all
within 1 %. Without three finished levels of the reference (``--levels 2``, a non-monotone series) the reference's
finest level stands for the converged value (said so). Scenes: cases/room; the 1 m bottleneck of docs/validation.md
and the 40 x 30 m hall of benchmarks/peer.py with 100 and 1 000 people (made there, under benchmarks/.cache/peer),
the paper's model (constant speed) and, for the bottleneck and the hall, the variant weidmann-push of
femcrowd/studies/recommended.py (Weidmann's law, push 0.2, slip walls, 1.9 on every door; the recommended settings
when this frontier was measured, the scenes' names keep that word): the explicit
LWR fluxes at cfl 1 (the reference), the linearly implicit ones at cfl 1, 2, 4, 8 on the median cell's step and
at cfl 4, 8 on the smallest cell's (cfl 1 and 2 there take at least half the explicit steps, each dearer).

    python benchmarks/frontier.py --scenes room
"""

import argparse
import math
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

import peer  # this script's folder is on sys.path: the scenes of the peer benchmark

from femcrowd import load_case
from femcrowd.studies.evacuation import observed, run_level, share_names, study
from femcrowd.studies.recommended import PUSH_CAPACITY, PUSHING, WALLS

IMPLICIT = ["scheme.transport=implicit"]
RULE = [*IMPLICIT, "time.cfl_quantile=0.5"]
LAW = [f"{k}={v}" for k, v in {**PUSHING, **WALLS}.items()]
RECOMMENDED = LAW + [f"boundary.capacity={{exit = {PUSH_CAPACITY}}}"]
HALL = LAW + [f"boundary.capacity={{west = {PUSH_CAPACITY}, east = {PUSH_CAPACITY}}}"]


def steps(law):
    """The step rules of a speed law's series: the explicit LWR fluxes first (the reference), then the implicit."""
    return [("explicit LWR", law, [1]), ("implicit LWR, median cell", law + RULE, [1, 2, 4, 8]),
            ("implicit LWR, smallest cell", law + IMPLICIT, [4, 8])]


#: per scene: its case directory (a function: the peer scenes are made on demand) and its series
#: (label, overrides, cfl values); the first series is the reference
SCENES = {
    "room": (lambda: Path("cases/room"), [("upwind", [], [0.5]), ("implicit, smallest cell", IMPLICIT, [2, 4]),
                                          ("implicit, median cell", RULE, [1, 2, 4])]),
    "bottleneck": (lambda: peer.scene("bottleneck", 90)[0], [
        ("upwind", [], [1]), ("implicit, median cell", RULE, [1, 2, 4])]),
    "bottleneck-recommended": (lambda: peer.scene("bottleneck", 90)[0], steps(RECOMMENDED)),
    "hall": (lambda: peer.scene("hall", 100)[0], [("implicit, median cell", RULE, [1]), ("upwind", [], [1])]),
    "hall-recommended": (lambda: peer.scene("hall", 100)[0], steps(HALL)),
    # the smallest cell's steps left out: in the hall they are the median cell's cfl 0.6 and 1.25 (hall-recommended)
    "hall-1000-recommended": (lambda: peer.scene("hall", 1000)[0], steps(HALL)[:2]),
}


def plan_mesh(directory, overrides, cfl) -> dict:
    """One run on the plan's mesh (``--levels 1``: a study needs two), as a row of a study."""
    names = [f"t {name}" for name in share_names(load_case(directory))]
    found = run_level(SimpleNamespace(case_dir=directory, overrides=[*overrides, f"time.cfl={cfl}"]))
    return {"level": 0, "cfl": cfl, **found, **dict(zip(names, found["times"]))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--levels", type=int, default=3, help="meshes of each series: mesh.refine 0..levels-1 (1: the "
                        "plan's mesh alone, no converged value)")
    args = parser.parse_args()
    for name in args.scenes:
        directory, series = SCENES[name]
        rows = []
        with tempfile.TemporaryDirectory() as tmp:
            for k, (label, overrides, cfls) in enumerate(series):
                if args.levels == 1:
                    found = [plan_mesh(directory(), overrides, c) for c in cfls]
                else:
                    found = study(directory(), args.levels, Path(tmp) / str(k), overrides, [float(c) for c in cfls],
                                  serial=True)[0]
                rows += [{**r, "label": f"{label}, cfl {r['cfl']:g}"} for r in found]
        times = [key for key in rows[0] if key.startswith("t ")] + ["flow"]
        first = [r for r in rows if r["label"] == rows[0]["label"]]
        converged = [observed([r[t] for r in first], [r["h"] for r in first])[2][-1] for t in times]
        how = "Richardson"
        if not all(map(math.isfinite, converged)):
            converged, how = [first[-1][t] for t in times], f"its level {first[-1]['level']}, not converged"
        print(f"\n{name}: reference ({rows[0]['label']}, {how}) " + ", ".join(f"{c:.4g}" for c in converged))
        print("| series | level | cells | steps | CPU (s) | " + " | ".join(f"{t} (%)" for t in times) + " |")
        print("|---|---:|---:|---:|---:|" + "---:|" * len(times))
        within = []
        for r in rows:
            errors = [100 * (r[t] - c) / c for t, c in zip(times, converged)]
            print(f"| {r['label']} | {r['level']} | {r['cells']} | {r['steps']} | {r['cpu_seconds']:.3g} | "
                  + " | ".join(f"{r[t]:.4g} ({e:+.2f})" for t, e in zip(times, errors)) + " |")
            if all(abs(e) <= 1 for e in errors):   # nan (a level that did not finish) is never within
                within.append(r)
        best = min(within, key=lambda r: r["cpu_seconds"], default=None)
        print("fastest within 1 %: " + (f"{best['label']}, level {best['level']}, {best['cpu_seconds']:.3g} CPU s"
                                        if best else "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
