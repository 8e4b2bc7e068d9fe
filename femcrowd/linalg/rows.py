"""Rows of a CSR matrix, gathered with plain numpy, and what the projection takes from them: A[cells] @ x and the
lower triangle of A[cells][:, cells].

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


def matvec(gathered: Rows, x: np.ndarray) -> np.ndarray:
    """A[cells] @ x from the gathered rows (each row summed in the order of its entries, as scipy's mat-vec)."""
    count = np.diff(gathered.indptr)
    return np.bincount(np.repeat(np.arange(len(count)), count), gathered.data * x[gathered.indices], len(count))


def lower_block(gathered: Rows, cells: np.ndarray):
    """rows, cols, values of the lower triangle of A[cells][:, cells] in compressed-column order (what
    cholmod.lower_pattern gives for that block, for A without duplicate entries), from the gathered rows A[cells]."""
    order = np.argsort(cells)
    at = np.minimum(np.searchsorted(cells[order], gathered.indices), len(cells) - 1)
    column = order[at]                       # the position in cells of each entry's column
    row = np.repeat(np.arange(len(cells)), np.diff(gathered.indptr))
    keep = (cells[column] == gathered.indices) & (column <= row)
    row, column = row[keep], column[keep]
    by_column = np.lexsort((row, column))
    return row[by_column], column[by_column], gathered.data[keep][by_column]
