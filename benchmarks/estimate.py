"""`femcrowd info`'s run time against the wall time of `femcrowd run` (default options, a fresh process each,
as a user types them) for every shipped case (every case.toml under cases/); prints a table with the ratio
estimated / actual and the worst ratio (the factor by which the estimate is furthest off, either way).

    python benchmarks/estimate.py                         # every shipped case
    python benchmarks/estimate.py cases/room cases/bottleneck
"""

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FEMCROWD = Path(sys.executable).parent / "femcrowd"
ROOT = Path(__file__).resolve().parent.parent
SECONDS = re.compile(r"run time of femcrowd run: about ([\d.e+-]+) (s|min)")


def estimated(case: Path) -> tuple:
    """The seconds `femcrowd info CASE` estimates, and the line saying what that is based on."""
    out = subprocess.run([FEMCROWD, "info", case], check=True, capture_output=True, text=True).stdout
    match = SECONDS.search(out)
    based = out[match.end():].splitlines()[1].strip()
    return float(match[1]) * (60 if match[2] == "min" else 1), based


def actual(case: Path, out: Path) -> float:
    """The wall seconds of `femcrowd run CASE --out OUT -q`."""
    tic = time.perf_counter()
    subprocess.run([FEMCROWD, "run", case, "--out", out, "-q"], check=True, capture_output=True)
    return time.perf_counter() - tic


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", type=Path, help="case directories (default: every shipped case)")
    args = parser.parse_args()
    cases = args.cases or sorted(file.parent for file in (ROOT / "cases").rglob("case.toml"))
    print("| case | estimated s | actual s | ratio | based on |\n|---|---:|---:|---:|---|")
    worst = (1.0, None)
    with tempfile.TemporaryDirectory() as tmp:
        for k, case in enumerate(cases):
            guess, based = estimated(case)
            wall = actual(case, Path(tmp) / str(k))
            ratio = guess / wall
            worst = max(worst, (max(ratio, 1 / ratio), case.name))
            name = case.resolve().relative_to(ROOT / "cases") if (ROOT / "cases") in case.resolve().parents else case
            print(f"| {name} | {guess:.2f} | {wall:.2f} | {ratio:.2f} | {based.removeprefix('based on ')} |",
                  flush=True)
    print(f"\nworst ratio: a factor {worst[0]:.2f} ({worst[1]})")


if __name__ == "__main__":
    main()
