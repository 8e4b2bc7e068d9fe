"""Algebraic multigrid for the projection's systems too large to factorise: conjugate gradients
preconditioned by a Ruge-Stuben V-cycle (Ruge, Stuben 1987; pyamg)."""

import numpy as np
import pyamg

from .vectors import dot


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

    The second pass keeps the CG iterations independent of the mesh size despite the clipped, large
    transmissibilities of nearly cocircular pairs; one-sided sweeps are cheaper than symmetric ones
    (the measurements: docs/performance.md).
    """
    return pyamg.ruge_stuben_solver(K, CF=("RS", {"second_pass": True}),
                                    presmoother=("gauss_seidel", {"sweep": "forward"}),
                                    postsmoother=("gauss_seidel", {"sweep": "backward"}))


def vcycle(ml, b, level=0):
    """One V-cycle of a pyamg hierarchy from x = 0 (what ml.aspreconditioner() applies, without the
    residual norms that pyamg computes with multithreaded BLAS, which spin on a loaded machine:
    docs/performance.md, "Threads")."""
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

    Returns (x, iterations, converged). Dot products on the calling thread (vectors.dot).
    """
    x = np.array(x0, float)
    r = rhs - K @ x
    if np.all(np.abs(r) <= threshold(x)):
        return x, 0, True
    z = precondition(r)
    p = z.copy()
    rz = dot(r, z)
    for iteration in range(1, maxiter + 1):
        q = K @ p
        alpha = rz / dot(p, q)
        x += alpha * p
        r -= alpha * q
        if np.all(np.abs(r) <= threshold(x)):
            r = rhs - K @ x  # the recurred residual drifts: confirm with the true one
            if np.all(np.abs(r) <= threshold(x)):
                return x, iteration, True
        z = precondition(r)
        rz, rz_old = dot(r, z), rz
        p *= rz / rz_old
        p += z
    return x, maxiter, False

