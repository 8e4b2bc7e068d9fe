"""Linear solvers of the projection: A_SS x = b on a saturated set S of the two-point Laplacian A.

- EnvelopeCholesky: sparse Cholesky (CHOLMOD, through cvxopt) of A_SS for every S inside a
  fixed envelope of cells, one symbolic analysis per envelope, one numeric factorisation per
  S, and none for an S that grows by a few cells (bordering);
- cholesky_solve: one CHOLMOD solve of a small system (the predictor's band solves);
- amg_hierarchy, vcycle, pcg: conjugate gradients preconditioned by a Ruge-Stuben AMG V-cycle
  (pyamg), for systems too large to factorise.
"""

from contextlib import contextmanager

import cvxopt
import cvxopt.cholmod as cholmod
import numpy as np
import pyamg
import scipy.sparse as sp

#: a factorisation is replaced by a tighter one when S shrinks below SHRINK times the S it was made for
SHRINK = 0.6
#: an S that grows by at most this many cells from the factorised one is solved by bordering (a Schur
#: complement on the new cells: k + 1 forward and one backward substitution with the kept factor) instead
#: of a new numeric factorisation. `python benchmarks/bordering.py --radius 7` and `--radius 10` (2.6 10^4
#: to 4.5 10^5 unknowns, nested-dissection order; cvxopt's CHOLMOD substitutes column by column): 0.21-0.25
#: of a factorisation and solve for k = 1, 0.57-0.92 for k = 8, 1.0-1.6 for k = 16 (1.5-1.6 at 10^6 triangles)
BORDER_MAX = 8


class EnvelopeCholesky:
    """Sparse Cholesky factorisation of A_SS for every S inside a fixed envelope E of cells.

    The matrix factorised is K = T A_EE T + diag(A_EE) (I - T), T = diag(1_S): A_SS on S and
    its diagonal elsewhere (so x = 0 off S). Its sparsity pattern is that of A_EE whatever S
    is, so the symbolic analysis (fill-reducing ordering, supernodes) is done once per
    envelope and a new S costs one numeric factorisation. CHOLMOD (supernodal, through cvxopt)
    rather than scipy's SuperLU: on the 2.6 10^5-cell saturated zone of the benchmark hall it
    factorises in 0.17 s, where a Ruge-Stuben set-up takes 0.30 s; SuperLU took 8x as long as
    CHOLMOD already at 2.6 10^4 cells (docs/performance.md).

    An S that grows from the factorised S_0 by a few cells J (the last stragglers of an
    active-set iteration) is solved by bordering: with C = A_{S_0 J},

        Sigma = A_JJ - C^T A_00^{-1} C,   x_J = Sigma^{-1} (b_J - C^T A_00^{-1} b_0),
        x_0 = A_00^{-1} (b_0 - C x_J),

    through the factor P A_00 P^T = L D L^T: |J| + 1 forward substitutions and one backward.
    """

    def __init__(self, A, envelope, size, order=None):
        """envelope: the cells of E (sorted); size: |S| of the S that E was made around; order: rank
        of every cell in a fill-reducing order (None: CHOLMOD's own choice)."""
        self.A, self.cells, self.size = A, envelope, size
        self.position = np.full(A.shape[0], -1, np.intp)  # position of a cell in E (-1: not in E)
        self.position[envelope] = np.arange(len(envelope))
        lower = sp.tril(A[envelope][:, envelope], format="csc")
        lower.sort_indices()  # column by column, rows sorted: cvxopt's storage order
        self.row = lower.indices
        self.col = np.repeat(np.arange(len(envelope)), np.diff(lower.indptr))
        self.values = lower.data
        self.diagonal = self.row == self.col
        self.matrix = cvxopt.spmatrix(1.0, cvxopt.matrix(self.row.astype(int)), cvxopt.matrix(self.col.astype(int)),
                                      (len(envelope), len(envelope)))
        if order is None:
            self.symbolic = cholmod.symbolic(self.matrix, uplo="L")
        else:
            with _cholmod_options(nmethods=1):  # that order only: CHOLMOD would also try AMD
                self.symbolic = cholmod.symbolic(self.matrix, p=cvxopt.matrix(np.argsort(order[envelope])), uplo="L")
        self.active = None                 # positions of the factorised S in E
        self.mask = np.zeros(len(envelope), bool)  # the factorised S as a mask on E
        self.inverse_d = None              # D^{-1} of the factor (ones for a supernodal L L^T)

    def fits(self, cells):
        """cells inside the envelope, and not fewer than SHRINK times the S it was made around
        (else a new, tighter one pays off)."""
        return len(cells) >= SHRINK * self.size and bool(np.all(self.position[cells] >= 0))

    def factorised(self):
        """The cells of the factorised S (sorted)."""
        return self.cells[self.active]

    def needs_factorisation(self, cells):
        """False when S = cells is the factorised S or grows from it by at most BORDER_MAX cells."""
        if self.active is None:
            return True
        kept = np.count_nonzero(self.mask[self.position[cells]])
        return kept != len(self.active) or len(cells) - kept > BORDER_MAX

    def prepare(self, cells):
        """Numeric factorisation of K for S = cells when needed; returns whether one was made."""
        if not self.needs_factorisation(cells):
            return False
        self.active = self.position[cells]
        self.mask[:] = False
        self.mask[self.active] = True
        keep = self.diagonal | (self.mask[self.row] & self.mask[self.col])
        self.matrix.V = cvxopt.matrix(np.where(keep, self.values, 0.0))
        cholmod.numeric(self.matrix, self.symbolic)
        self.inverse_d = None
        return True

    def solve(self, cells, rhs):
        """x on S = cells with A_SS x = rhs (after prepare(cells))."""
        at = self.position[cells]
        old = self.mask[at]
        if old.all():
            return self._substitute(rhs)
        new = at[~old]
        rows = self.A[self.cells[new]]
        k = len(new)
        row = np.repeat(np.arange(k), np.diff(rows.indptr))
        position = self.position[rows.indices]
        coupled = (position >= 0) & self.mask[position]  # entries of C^T = A_{J S_0}
        j = np.minimum(np.searchsorted(new, position), k - 1)
        within = new[j] == position                       # entries of A_JJ
        A_JJ = np.zeros((k, k))
        np.add.at(A_JJ, (row[within], j[within]), rows.data[within])
        V = np.zeros((len(self.cells), k + 1), order="F")  # [b_0 | C], then L^{-1} P [b_0 | C]
        V[self.active, 0] = rhs[old]
        V[position[coupled], 1 + row[coupled]] = rows.data[coupled]
        V = self._forward(V)
        if self.inverse_d is None:
            self.inverse_d = np.array(self._apply(np.ones(len(self.cells)), 6)).ravel()
        DV = self.inverse_d[:, None] * V
        sigma = A_JJ - V[:, 1:].T @ DV[:, 1:]
        x = np.empty(len(at))
        x[~old] = np.linalg.solve(sigma, rhs[~old] - V[:, 1:].T @ DV[:, 0])
        x[old] = self._backward(DV[:, 0] - DV[:, 1:] @ x[~old])[self.active]
        return x

    def _substitute(self, rhs):
        """K^{-1} b on the factorised S, for b = rhs there and 0 elsewhere."""
        b = np.zeros(len(self.cells))
        b[self.active] = rhs
        return np.array(self._apply(b, 0)).ravel()[self.active]

    def _forward(self, b):
        """L^{-1} P b."""
        return np.array(self._apply(self._apply(b, 7), 4)).reshape(b.shape, order="F")

    def _backward(self, y):
        """P^T L^{-T} y (y already scaled by D^{-1})."""
        return np.array(self._apply(self._apply(y, 5), 8)).ravel()

    def _apply(self, b, system):
        """CHOLMOD's solve of one of its systems (0: K, 4: L, 5: L^T, 6: D, 7: P, 8: P^T), in place
        for a cvxopt matrix b, else on a copy."""
        b = b if isinstance(b, cvxopt.matrix) else cvxopt.matrix(b)
        cholmod.solve(self.symbolic, b, sys=system)
        return b


@contextmanager
def _cholmod_options(**options):
    """CHOLMOD options (cvxopt's module-wide dict) for the calls in the block, restored after it."""
    saved = dict(cholmod.options)
    cholmod.options.update(options)
    try:
        yield
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)


def cholesky_solve(K, rhs, order):
    """K x = rhs for a small SPD sparse matrix K: CHOLMOD on its lower triangle, in the fill-reducing
    order given by the ranks `order` of its rows (one symbolic analysis, one factorisation)."""
    lower = sp.tril(K, format="coo")
    matrix = cvxopt.spmatrix(lower.data, cvxopt.matrix(lower.row.astype(int)), cvxopt.matrix(lower.col.astype(int)),
                             K.shape)
    x = cvxopt.matrix(np.asarray(rhs, float))
    with _cholmod_options(nmethods=1):  # that order only
        cholmod.linsolve(matrix, x, p=cvxopt.matrix(np.argsort(order)), uplo="L")
    return np.array(x).ravel()


class Hierarchy:
    """A Ruge-Stuben hierarchy of K on `cells` (sorted)."""

    def __init__(self, K, cells):
        self.cells = cells
        self.ml = amg_hierarchy(K)

    def vcycle(self, r):
        return vcycle(self.ml, r)


def amg_hierarchy(K):
    """Ruge-Stuben hierarchy with the second pass of the C/F splitting, forward Gauss-Seidel before
    and backward after the coarse correction (a symmetric V-cycle).

    Measured on the saturated zone of the benchmark hall (docs/performance.md): with pyamg's
    default splitting CG needed 45 iterations at 3 10^4 unknowns and 101 at 3 10^5 (the clipped,
    large transmissibilities of nearly cocircular pairs); with the second pass 18 and 19, for a
    set-up 1.7x as long. One-sided sweeps are 30 % faster than the default symmetric ones.
    """
    return pyamg.ruge_stuben_solver(K, CF=("RS", {"second_pass": True}),
                                    presmoother=("gauss_seidel", {"sweep": "forward"}),
                                    postsmoother=("gauss_seidel", {"sweep": "backward"}))


def vcycle(ml, b, level=0):
    """One V-cycle of a pyamg hierarchy from x = 0 (what ml.aspreconditioner() applies, without the
    residual norms that pyamg computes with multithreaded BLAS: on a loaded 2-core machine those
    dot products alone made CG 10x slower)."""
    lev = ml.levels[level]
    if level == len(ml.levels) - 1:
        return ml.coarse_solver(lev.A, b)
    x = np.zeros_like(b)
    lev.presmoother(lev.A, x, b)
    x += lev.P @ vcycle(ml, lev.R @ (b - lev.A @ x), level + 1)
    lev.postsmoother(lev.A, x, b)
    return x


def pcg(K, rhs, x0, precondition, threshold, maxiter):
    """Preconditioned conjugate gradients for the SPD K from x0, until |r_i| <= threshold(x)_i for every i.

    Returns (x, iterations, converged). Dot products use einsum (no BLAS threads).
    """
    x = np.array(x0, float)
    r = rhs - K @ x
    if np.all(np.abs(r) <= threshold(x)):
        return x, 0, True
    z = precondition(r)
    p = z.copy()
    rz = _dot(r, z)
    for iteration in range(1, maxiter + 1):
        q = K @ p
        alpha = rz / _dot(p, q)
        x += alpha * p
        r -= alpha * q
        if np.all(np.abs(r) <= threshold(x)):
            r = rhs - K @ x  # the recurred residual drifts: confirm with the true one
            if np.all(np.abs(r) <= threshold(x)):
                return x, iteration, True
        z = precondition(r)
        rz, rz_old = _dot(r, z), rz
        p *= rz / rz_old
        p += z
    return x, maxiter, False


def _dot(a, b):
    return float(np.einsum("i,i->", a, b))
