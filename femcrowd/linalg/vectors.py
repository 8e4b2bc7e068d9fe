"""Vector reductions of the hot path, kept out of BLAS.

numpy's ``a @ b`` of two vectors calls BLAS's dot product, which OpenBLAS may run on several
threads: for the vectors of one step (10^4-10^6 entries) that gains nothing, and with another
process on the cores the threads spin (docs/performance.md, "Threads").
``einsum`` sums in numpy's own loop, on the calling thread.
"""

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """sum_i a_i b_i, on the calling thread."""
    return float(np.einsum("i,i->", a, b))
