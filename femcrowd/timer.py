"""The seconds a run spends in each phase (summary.json "timing"): one timer, the phases recorded by a context
manager, ``with timer("projection"): ...``, summed over the calls."""

import time
from collections import defaultdict
from contextlib import contextmanager


class Timer:
    """Seconds per phase; ``seconds`` maps each phase to its total."""

    def __init__(self):
        self.seconds = defaultdict(float)

    @contextmanager
    def __call__(self, phase: str):
        tic = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[phase] += time.perf_counter() - tic

    def __getitem__(self, phase: str) -> float:
        return self.seconds[phase]

    def items(self):
        return self.seconds.items()
