"""Sparse Cholesky factorisation (CHOLMOD, Chen, Davis, Hager, Rajamanickam 2008, through cvxopt):
the one wrapper of the macro projection and the disc model.

A :class:`Cholesky` is made for one sparsity pattern: the symbolic analysis
(fill-reducing order, supernodes) is done once, then every new set of values
costs one numeric factorisation. CHOLMOD's options are cvxopt's module-wide
dict; here each object carries its own and applies them only for the
duration of its calls, so the two models never see each other's settings.
"""

from contextlib import contextmanager

import cvxopt
import cvxopt.cholmod as cholmod
import numpy as np
import scipy.sparse as sp

#: CHOLMOD's solve systems (cholmod_solve's sys argument)
SYSTEM = {"A": 0, "L": 4, "Lt": 5, "D": 6, "P": 7, "Pt": 8}


@contextmanager
def scoped_options(**options):
    """CHOLMOD options for the calls in the block, the previous ones restored after it."""
    saved = dict(cholmod.options)
    cholmod.options.update(options)
    try:
        yield
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)


class Cholesky:
    """P K P^T = L D L^T (or L L^T) for the SPD matrices K of one sparsity pattern.

    rows, cols: the entries of the lower triangle in compressed-column order (sorted by column,
    then row), each entry once; order: rank of every row in a fill-reducing order (None: CHOLMOD
    chooses); options: CHOLMOD options for every call (e.g. supernodal=2).
    """

    def __init__(self, rows: np.ndarray, cols: np.ndarray, n: int, order=None, **options):
        self.n = int(n)
        self.options = dict(options, nmethods=1) if order is not None else dict(options)
        self.matrix = cvxopt.spmatrix(1.0, cvxopt.matrix(np.asarray(rows, int)),
                                      cvxopt.matrix(np.asarray(cols, int)), (self.n, self.n))
        given = {} if order is None else {"p": cvxopt.matrix(np.argsort(order).astype(int))}
        with scoped_options(**self.options):  # nmethods = 1: that order only (CHOLMOD also tries AMD)
            self.symbolic = cholmod.symbolic(self.matrix, uplo="L", **given)

    def factorise(self, values: np.ndarray) -> None:
        """Numeric factorisation for these values of the pattern's entries (in its order)."""
        self.matrix.V = cvxopt.matrix(np.asarray(values, float))
        with scoped_options(**self.options):
            cholmod.numeric(self.matrix, self.symbolic)

    def solve(self, b, system: str = "A"):
        """One of CHOLMOD's solves (K x = b, or with L, L^T, D, P, P^T): in place for a cvxopt
        matrix b, else on a copy (a cvxopt matrix is returned; np.array(x) reads it)."""
        b = b if isinstance(b, cvxopt.matrix) else cvxopt.matrix(np.array(b, float, order="F"))
        with scoped_options(**self.options):
            cholmod.solve(self.symbolic, b, sys=SYSTEM[system])
        return b


def lower_pattern(K: sp.spmatrix):
    """rows, cols, values of the lower triangle of K in compressed-column order."""
    lower = sp.tril(K, format="csc")
    lower.sum_duplicates()
    lower.sort_indices()
    return lower.indices, np.repeat(np.arange(K.shape[1]), np.diff(lower.indptr)), lower.data


def solve_spd(lower, n: int, rhs: np.ndarray, order: np.ndarray) -> np.ndarray:
    """K x = rhs for a small SPD sparse matrix K of order n given by the rows, cols, values of its lower triangle
    (lower_pattern), in the fill-reducing order given by the ranks `order` of its rows (one symbolic analysis, one
    factorisation, one solve)."""
    rows, cols, values = lower
    factor = Cholesky(rows, cols, n, order)
    factor.factorise(values)
    return np.array(factor.solve(rhs)).ravel()
