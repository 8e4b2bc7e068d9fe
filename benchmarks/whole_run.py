"""Wall time of a whole `femcrowd run CASE` as a user types it (a fresh process: start-up, checks, run, output;
default threads), alternated with the same command on a baseline checkout, over `--repeat` rounds; prints the
medians and their difference (the cost of the checks of docs/case-format.md: mesh checks, plausibility,
limits, the output directory's lock).

    python benchmarks/whole_run.py --baseline /tmp/prev               # cases/room
    python benchmarks/whole_run.py cases/entrance --baseline /tmp/prev --repeat 7
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from alternating import median, rounds  # this script's folder is on sys.path

FEMCROWD = Path(sys.executable).parent / "femcrowd"


def timed_run(case, code, out) -> dict:
    """One `femcrowd run CASE --out OUT --force -q` with femcrowd from checkout `code` (None: this one)."""
    env = dict(os.environ)
    if code is not None:
        env["PYTHONPATH"] = str(code)
    tic = time.perf_counter()
    subprocess.run([FEMCROWD, "run", case, "--out", out, "--force", "-q"], env=env, check=True, capture_output=True)
    return {"wall": time.perf_counter() - tic}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", nargs="?", default="cases/room")
    parser.add_argument("--baseline", required=True, help="a femcrowd checkout to compare with (git worktree)")
    parser.add_argument("--repeat", type=int, default=5, help="rounds of the two configurations")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        configs = [("baseline", args.baseline, Path(tmp) / "baseline"), ("this checkout", None, Path(tmp) / "this")]
        runs = rounds(configs, args.repeat, lambda code, out: timed_run(args.case, code, out))
    before, after = median(runs["baseline"], "wall"), median(runs["this checkout"], "wall")
    print(f"femcrowd run {args.case}, medians of {args.repeat} alternated runs")
    print(f"| baseline ({args.baseline}) | this checkout | difference |\n|---:|---:|---:|\n"
          f"| {before:.2f} s | {after:.2f} s | {after - before:+.2f} s |")


if __name__ == "__main__":
    main()
