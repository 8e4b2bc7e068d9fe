"""User CPU time of `femcrowd run` on a shared machine: femcrowd's own thread setting against one BLAS thread.

A CPU-bound process runs beside femcrowd (as during a convergence study, whose dask workers run side
by side). The scene is the saturated evacuation (exact solution 3, k = 2) on 31 104 cells. Each
variant runs in its own process, alternately, `--rounds` times; printed: median wall and user CPU
seconds per variant and the ratio of user CPU times to the run with OPENBLAS_NUM_THREADS=1.

    python benchmarks/threads.py                          # this checkout, 3 rounds
    python benchmarks/threads.py --source /tmp/old-femcrowd  # also another checkout's code (PYTHONPATH)
"""

import argparse
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASE = ["cases/saturated-exit", "--set", "mesh.refine=3", "--set", 'velocity.ux="-(1 + 2 * x)"',
        "--set", "time.end=0.3", "--set", "output.every=0.3", "-q", "--force"]


def busy(stop):
    """A CPU-bound process (pure Python: no BLAS of its own)."""
    x = 0
    while not stop.is_set():
        x = (x * 1103515245 + 12345) % 2**31


def timed_run(source, env, extra, out):
    """(wall, user CPU) seconds of one `femcrowd run` in a new process."""
    code = "import sys; from femcrowd.cli import main; sys.exit(main())"
    env = {**os.environ, **env}
    if source:
        env["PYTHONPATH"] = str(source)
    tic = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code, "run", *CASE, "--out", out, *extra], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - tic
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(proc.stderr.read().decode())
    return wall, usage.ru_utime


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--source", type=Path, help="another checkout to time too (its femcrowd on PYTHONPATH)")
    args = parser.parse_args()
    single = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    variants = {"OPENBLAS_NUM_THREADS=1": (None, single, []), "default (femcrowd sets 1 thread)": (None, {}, []),
                "--threads 2": (None, {}, ["--threads", "2"])}
    if args.source:
        variants[f"{args.source} default"] = (args.source, {}, [])
        variants[f"{args.source} OPENBLAS_NUM_THREADS=1"] = (args.source, single, [])
    stop = multiprocessing.Event()
    competitor = multiprocessing.Process(target=busy, args=(stop,))
    competitor.start()
    times = {name: [] for name in variants}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(args.rounds):
                for name, (source, env, extra) in variants.items():
                    times[name].append(timed_run(source, env, extra, str(Path(tmp) / "out")))
    finally:
        stop.set()
        competitor.join()
    reference = np.median([user for _, user in times["OPENBLAS_NUM_THREADS=1"]])
    print(f"femcrowd run {' '.join(CASE[:1])} (31 104 cells, 0.3 s), one CPU-bound process beside it, "
          f"{args.rounds} rounds, medians:")
    print(f"{'variant':<44} {'wall [s]':>9} {'user CPU [s]':>13} {'user / 1 thread':>16}")
    for name, values in times.items():
        wall, user = np.median([w for w, _ in values]), np.median([u for _, u in values])
        print(f"{name:<44} {wall:9.2f} {user:13.2f} {user / reference:16.2f}")


if __name__ == "__main__":
    main()
