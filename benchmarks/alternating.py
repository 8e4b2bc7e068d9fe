"""Configurations of a benchmark timed in alternated rounds, each run in a fresh process, so that a slow period
of this shared machine hits them all (benchmarks/populations.py, benchmarks/capacity.py).

A script calls itself with ``--worker ARGS`` in a new process (on the femcrowd of a given checkout, for a
before/after comparison); the worker prints one JSON line, which :func:`in_process` returns.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time

import numpy as np


def arguments(parser, baseline: str):
    """The options every such benchmark has: --steps, --repeat, --baseline (with this help) and the hidden
    --worker of its child processes."""
    parser.add_argument("--steps", type=int, default=20, help="timed steps per run (after 3 warm-up steps)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the configurations")
    parser.add_argument("--baseline", help=baseline)
    parser.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    return parser.parse_args()


def timed_steps(model, steps: int, warm: int = 3):
    """`warm` steps, then `steps` timed ones: (median seconds of a step, the solver's seconds per step by phase,
    the steps' infos)."""
    for _ in range(warm):
        model.step(math.inf)
    before = dict(model.solver.timers.items())
    durations, infos = [], []
    for _ in range(steps):
        tic = time.perf_counter()
        infos.append(model.step(math.inf))
        durations.append(time.perf_counter() - tic)
    timers = {name: (value - before.get(name, 0.0)) / steps for name, value in model.solver.timers.items()}
    return float(np.median(durations)), timers, infos


def in_process(script, args, code=None, env=None) -> dict:
    """Run `script --worker *args` in a fresh process (on the femcrowd checkout `code`, None: this one, with the
    extra environment `env`) and return the JSON of its last line."""
    env = {**os.environ, **(env or {})}
    if code is not None:
        env["PYTHONPATH"] = str(code)
    done = subprocess.run([sys.executable, str(script), "--worker", *map(str, args)], env=env, capture_output=True,
                          text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def rounds(configs, repeat: int, measure) -> dict:
    """{name: [measure(code, value) of each round]} for the configurations (name, code, value): one after the
    other, `repeat` times (code: a femcrowd checkout, or None)."""
    runs = {name: [] for name, _, _ in configs}
    for _ in range(repeat):
        for name, code, value in configs:
            runs[name].append(measure(code, value))
    return runs


def median(runs, key) -> float:
    return float(np.median([r[key] for r in runs]))



def by_size(sizes, configs, repeat: int, measure):
    """The runs {name: [one per round]} at each size, the configurations in alternated rounds;
    measure(size, code, value) -> dict (a worker makes and caches its mesh before it times anything)."""
    for size in sizes:
        yield rounds(configs, repeat, lambda code, value: measure(size, code, value))
