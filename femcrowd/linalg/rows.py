"""Rows of a CSR matrix, gathered with plain numpy.

scipy's ``A[cells]`` checks and converts its indices and builds a new matrix: about three times the cost of
the gather itself for the few hundred rows of a small projection, and it is taken several times per step
(docs/performance.md, "Small scenes"). The result holds the same arrays, in the same order.
"""

from typing import NamedTuple

import numpy as np


class Rows(NamedTuple):
    """The rows of A at some cells, in CSR form: row i holds indices[indptr[i]:indptr[i + 1]] and data there."""

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray


def rows(A, cells: np.ndarray) -> Rows:
    """The rows of the CSR matrix A at `cells` (an index array), as A[cells] gives them."""
    start = A.indptr[cells]
    count = A.indptr[cells + 1] - start
    indptr = np.zeros(len(cells) + 1, A.indptr.dtype)
    np.cumsum(count, out=indptr[1:])
    entries = np.repeat(start - indptr[:-1], count) + np.arange(indptr[-1])
    return Rows(indptr, A.indices[entries], A.data[entries])
