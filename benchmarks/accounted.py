"""The share of a run's wall time that no timed phase accounts for (summary.json "timing"): `femcrowd run CASE`
for the given shipped cases (default: those of tests/driver/test_cases.py's invariants, the disc case too),
the unaccounted seconds and their share; exit code 1 if one is more than 5 % of the wall time and 50 ms (a
short run loses that much to scheduling between phases). A measure for a quiet machine: on a loaded one the
scheduler's pauses fall between the phases as well as in them. The tests check only what holds whatever the
load: every phase non-negative, their sum at most the wall time.

    python benchmarks/accounted.py
    python benchmarks/accounted.py cases/route-choice cases/narrow-door-micro
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

FEMCROWD = Path(sys.executable).parent / "femcrowd"
ROOT = Path(__file__).resolve().parent.parent


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", type=Path)
    args = parser.parse_args()
    cases = args.cases or sorted(p.parent for p in (ROOT / "cases").glob("*/case.toml"))
    worst = 0.0
    print(f"{'case':<28} {'wall (s)':>9} {'unaccounted (s)':>16} {'share':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            out = Path(tmp) / case.name
            subprocess.run([FEMCROWD, "run", case, "--out", out, "-q"], check=True, capture_output=True)
            timing = json.loads((out / "summary.json").read_text())["timing"]
            wall = timing.pop("wall")
            lost = wall - sum(timing.values())
            print(f"{case.name:<28} {wall:9.2f} {lost:16.3f} {lost / wall:7.1%}")
            if lost > 0.05:
                worst = max(worst, lost / wall)
    print(f"worst share beyond 50 ms: {worst:.1%} (limit 5 %)")
    sys.exit(1 if worst > 0.05 else 0)


if __name__ == "__main__":
    main()
