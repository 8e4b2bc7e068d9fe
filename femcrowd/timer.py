"""Where the seconds go: the phases of a run (summary.json "timing"), recorded by a context manager,
``with timer("projection"): ...``, summed over the calls; :func:`timed` adds a phase's seconds to any dict (the
projection's info); a :class:`Stopwatch` gives the seconds since it started (a step, a study). The one place
femcrowd reads the clock."""

import os
import time
from collections import defaultdict
from contextlib import contextmanager


@contextmanager
def timed(seconds: dict, phase: str):
    """Add the seconds spent in the block to ``seconds[phase]``."""
    tic = time.perf_counter()
    try:
        yield
    finally:
        seconds[phase] = seconds.get(phase, 0.0) + time.perf_counter() - tic


class Timer:
    """Seconds per phase; ``seconds`` maps each phase to its total. A phase timed inside another (the
    measurements inside a step's projection) is booked to itself alone: the phases add up to the time spent.

    ``with timer(phase):`` is the Timer itself as the context (no generator per phase, as contextlib's would make):
    what it costs outside its clock readings falls in no phase, and a small scene opens several phases a step."""

    def __init__(self):
        self.seconds = defaultdict(float)
        self._phases = []   # the phases asked for and open, innermost last
        self._starts = []   # per open phase, when it started
        self._inner = []    # per open phase, the seconds of the phases timed inside it

    def __call__(self, phase: str) -> "Timer":
        self._phases.append(phase)
        return self

    def __enter__(self) -> None:
        self._inner.append(0.0)
        self._starts.append(time.perf_counter())

    def __exit__(self, *exc) -> bool:
        elapsed = time.perf_counter() - self._starts.pop()
        self.seconds[self._phases.pop()] += elapsed - self._inner.pop()
        if self._inner:
            self._inner[-1] += elapsed
        return False

    def __getitem__(self, phase: str) -> float:
        return self.seconds[phase]

    def items(self):
        return self.seconds.items()


def process_seconds() -> float:
    """Wall seconds since this process started: the interpreter's start-up and the imports so far. On Linux from
    /proc (the process's start and the uptime, both counted from the boot, to 0.01 s); elsewhere psutil (whose
    start times are counted from a boot time in whole seconds on Linux, hence not used there)."""
    try:
        with open("/proc/self/stat") as stat, open("/proc/uptime") as uptime:
            start = int(stat.read().rsplit(")", 1)[1].split()[19]) / os.sysconf("SC_CLK_TCK")   # field 22
            return max(float(uptime.read().split()[0]) - start, 0.0)
    except (OSError, ValueError, IndexError, AttributeError):
        import psutil

        return max(time.time() - psutil.Process().create_time(), 0.0)


class Stopwatch:
    """Started when made; ``seconds`` is the time since, ``cpu`` the CPU seconds of the process (all its threads)
    since: on a shared machine the CPU time is the fairer measure of a run's cost."""

    def __init__(self):
        self.start, self.cpu_start = time.perf_counter(), time.process_time()

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self.start

    @property
    def cpu(self) -> float:
        return time.process_time() - self.cpu_start
