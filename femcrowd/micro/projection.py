"""Projection of the desired velocities on the feasible set (seed 000 eqs. 15-17).

Solves the sparse QP

    min_v 1/2 |v - U|^2   s.t.   B v <= d          (d = D / tau)

whose KKT system is seed 000 eq. (16): u + B^T lambda = U, B u <= d,
lambda >= 0, (B u - d) . lambda = 0.

``method="exact"`` (default): semismooth Newton on the augmented Lagrangian
(proximal method of multipliers). For a multiplier estimate lambda the
function ``phi(v) = 1/2 |v - U|^2 + 1/(2 rho) |[lambda + rho (B v - d)]_+|^2``
is strongly convex and piecewise quadratic; its Newton matrix on the active
set A = {lambda + rho (B v - d) > 0} is ``I + rho B_A^T B_A``, symmetric
positive definite *whatever the rank of B_A* (jams with more contacts than
degrees of freedom, seed 000 Fig. 3, make B B^T singular). Newton with an
exact (piecewise-quadratic) line search terminates when the active set
repeats; then lambda <- [lambda + rho (B v - d)]_+ (the multiplier update)
and the loop goes on until the KKT residual is at round-off. The previous
step's multipliers warm-start the active set, so a step in a slowly moving
jam costs one or two sparse Cholesky factorisations (only the discs touched
by active contacts enter the matrix: the connected clusters of contacts).

``method="uzawa"``: seed 000 eq. (17), projected gradient on the dual with
a fixed step nu < 2 / ||B||^2, kept for comparison (slow in jams: its rate
degrades with cond(B B^T)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contacts import Constraints
from .linalg import default_backend, factor_spd

__all__ = ["ProjectionResult", "project", "kkt_residual"]


@dataclass
class ProjectionResult:
    """u: velocities (N, 2); lam: multipliers (m,); kkt: max KKT residual
    (stationarity, feasibility, complementarity, in velocity units);
    iterations: Newton steps (exact) or Uzawa sweeps; factorizations: sparse
    Cholesky factorisations; converged: kkt <= requested tolerance."""

    u: np.ndarray
    lam: np.ndarray
    iterations: int
    factorizations: int
    kkt: float
    converged: bool
    method: str

    @property
    def active(self) -> int:
        return int(np.count_nonzero(self.lam > 0))


def kkt_residual(C: Constraints, U, d, u, lam) -> float:
    """max of |u + B^T lam - U|, |min(lam, d - B u)| (feasibility + complementarity)."""
    U = np.asarray(U, float)
    stat = np.abs(u + C.rmatvec(lam) - U).max() if C.N else 0.0
    if C.m == 0:
        return float(stat)
    nat = np.abs(np.minimum(lam, d - C.matvec(u))).max()
    return float(max(stat, nat))


def project(
    C: Constraints,
    U,
    d,
    *,
    method: str = "exact",
    lam0=None,
    tol: float = 1e-12,
    max_iter: int | None = None,
    rho: float = 1e4,
    nu: float | None = None,
    backend: str | None = None,
) -> ProjectionResult:
    """Project U (N, 2) on {v : B v <= d} (seed 000 eq. 15-16).

    tol is relative to max(1, max|U|); lam0 warm-starts the multipliers.
    """
    U = np.asarray(U, dtype=float).reshape(C.N, 2)
    d = np.asarray(d, dtype=float).reshape(C.m)
    lam = np.zeros(C.m) if lam0 is None else np.maximum(np.asarray(lam0, float).reshape(C.m), 0.0)
    atol = tol * max(1.0, float(np.abs(U).max()) if C.N else 1.0)
    if method == "exact":
        return _ssn_alm(C, U, d, lam, atol, max_iter or 200, rho, backend or default_backend())
    if method == "uzawa":
        return _uzawa(C, U, d, lam, atol, max_iter or 100_000, nu)
    raise ValueError(f"unknown projection method {method!r} (exact, uzawa)")


# --------------------------------------------------------------------------
# exact: semismooth Newton augmented Lagrangian
# --------------------------------------------------------------------------


def _hessian(C: Constraints, act, rho):
    """Lower triangle (COO) of I + rho B_A^T B_A on the discs touched by A."""
    pa, wa = act[: C.mp], act[C.mp :]
    pi, pj, cp = C.pi[pa], C.pj[pa], C.cp[pa]
    wi, cw = C.wi[wa], C.cw[wa]
    discs = np.unique(np.concatenate([pi, pj, wi]))
    n = len(discs)
    idx = np.full(C.N, -1, dtype=np.intp)
    idx[discs] = np.arange(n)
    a, b, w = idx[pi], idx[pj], idx[wi]
    # diagonal blocks
    nodes = np.concatenate([a, b, w])
    c = np.concatenate([cp, cp, cw])
    xx, xy, yy = rho * c[:, 0] ** 2, rho * c[:, 0] * c[:, 1], rho * c[:, 1] ** 2
    # off-diagonal blocks (strictly lower: block row hi > block col lo)
    hi, lo = np.maximum(a, b), np.minimum(a, b)
    pxx, pxy, pyy = -rho * cp[:, 0] ** 2, -rho * cp[:, 0] * cp[:, 1], -rho * cp[:, 1] ** 2
    k = np.arange(n)
    rows = np.concatenate(
        [2 * nodes, 2 * nodes + 1, 2 * nodes + 1, 2 * hi, 2 * hi, 2 * hi + 1, 2 * hi + 1, 2 * k, 2 * k + 1]
    )
    cols = np.concatenate(
        [2 * nodes, 2 * nodes, 2 * nodes + 1, 2 * lo, 2 * lo + 1, 2 * lo, 2 * lo + 1, 2 * k, 2 * k + 1]
    )
    vals = np.concatenate([xx, xy, yy, pxx, pxy, pxy, pyy, np.ones(2 * n)])
    return discs, rows, cols, vals


def _line_search(v, U, delta, z, w, rho):
    """Exact minimiser in (0, 1] of the convex piecewise quadratic phi(v + a delta).

    phi'(a) = (v - U + a delta).delta + sum_i [z_i + a rho w_i]_+ w_i, w = B delta.
    """
    p0 = float(np.sum((v - U) * delta))
    p1 = float(np.sum(delta * delta))
    act0 = (z > 0) | ((z == 0) & (w > 0))
    C0 = p0 + float(np.dot(z[act0], w[act0]))
    C1 = p1 + rho * float(np.dot(w[act0], w[act0]))
    if C0 >= 0:  # not a descent direction (round-off level gradient)
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -z / (rho * w)
    ev = np.flatnonzero((t > 0) & (t < 1) & (w != 0))
    # derivative at a = 1
    z1 = z + rho * w
    a1 = z1 > 0
    if p0 + p1 + float(np.dot(z1[a1], w[a1])) <= 0:
        return 1.0
    if len(ev) == 0:
        return min(1.0, -C0 / C1) if C1 > 0 else 1.0
    o = ev[np.argsort(t[ev], kind="stable")]
    te = t[o]
    sgn = np.where(w[o] > 0, 1.0, -1.0)  # enter (w > 0) or leave (w < 0)
    c0 = np.concatenate([[C0], C0 + np.cumsum(sgn * z[o] * w[o])])
    c1 = np.concatenate([[C1], C1 + np.cumsum(sgn * rho * w[o] ** 2)])
    ends = np.concatenate([te, [1.0]])
    val = c0 + ends * c1
    k = int(np.argmax(val >= 0)) if np.any(val >= 0) else len(val) - 1
    if c1[k] <= 0:
        return float(ends[k])
    lo = 0.0 if k == 0 else float(te[k - 1])
    return float(min(max(-c0[k] / c1[k], lo), ends[k]))


def _ssn_alm(C: Constraints, U, d, lam, atol, max_iter, rho, backend):
    """Semismooth Newton / multiplier iterations in incremental (refinement) form.

    The residuals r1 = U - v - B^T lam and r2 = d - B v are evaluated without
    the factor rho, and the multipliers are updated by increments, so the
    result reaches round-off accuracy although rho is large (the large rho
    only makes each multiplier update contract by 1 / (1 + rho mu)).
    """
    N, m = C.N, C.m
    if m == 0:
        return ProjectionResult(U.copy(), lam, 0, 0, 0.0, True, "exact")
    scale = max(1.0, float(np.abs(U).max()), float(np.abs(d[np.isfinite(d)]).max(initial=0.0)))
    # |z| below eta is round-off (z = lam + rho (B v - d) carries rho * eps * |B v|)
    eta = 1e3 * rho * np.finfo(float).eps * scale
    gtol = min(0.5 * atol, max(1e-2 * atol, 1e-3 * eta))  # inner gradient at round-off
    if np.any(lam > 0):
        v = U - C.rmatvec(lam)
        forced = lam > 0
    else:
        v = U.copy()
        forced = None
    fact = fact_act = discs = None
    nfact = it = 0
    converged = False
    kkt = np.inf
    prev_step = None  # last multiplier increment (drift detection)

    def update(lam, z, act):
        """Multiplier update lam <- [z]_+ on A; when two successive increments are
        equal (inconsistent active set: lam drifts along a self-stress, B^T dlam = 0,
        at rate rho * residual), jump along the drift to the first lam_i = 0."""
        nonlocal prev_step
        new = np.maximum(np.where(act, z, 0.0), 0.0)
        step = new - lam
        if prev_step is not None:
            ds = np.abs(step - prev_step).max()
            sm = np.abs(step).max()
            dec = step < 0
            if sm > 0 and ds <= 1e-3 * sm and np.any(dec & (new > 0)):
                ratio = new[dec] / -step[dec]
                t = float(ratio.min())
                if t > 1.0:
                    new = np.maximum(new + t * step, 0.0)
                    new[np.flatnonzero(dec)[np.argmin(ratio)]] = 0.0
                    prev_step = None
                    return new
        prev_step = step
        return new

    while True:
        r1 = U - v - C.rmatvec(lam)
        r2 = d - C.matvec(v)
        kkt = max(np.abs(r1).max(), np.abs(np.minimum(lam, r2)).max())
        if kkt <= atol:
            converged = True
            break
        if it >= max_iter:
            break
        z = lam - rho * r2
        act = forced if forced is not None else z > 0
        # Newton matrix set: the active rows; a row whose z is round-off keeps its
        # previous status (both are generalised Hessians; flipping would zigzag)
        if forced is not None or fact_act is None:
            hact = act
        else:
            hact = (z > eta) | ((z > -eta) & fact_act)
        # Newton step for phi(.; lam): H_A delta = -grad phi = r1 + B^T(rho r2 on A, lam off A)
        rhs = r1 + C.rmatvec(np.where(act, rho * r2, lam))
        # the factor is reused when A differs from its set only in round-off rows
        # (any SPD matrix gives a descent direction; the line search does the rest)
        if fact_act is None or forced is not None or not np.array_equal(hact, fact_act):
            if np.any(hact):
                discs, rows, cols, vals = _hessian(C, hact, rho)
                fact = factor_spd(rows, cols, vals, 2 * len(discs), backend)
                nfact += 1
            else:
                discs, fact = np.zeros(0, np.intp), None
            fact_act = hact
        if np.abs(rhs).max() <= gtol and forced is None:
            # phi(.; lam) is minimised to round-off: multiplier update
            lam = update(lam, z, act)
            continue
        delta = rhs
        if fact is not None and len(discs):
            delta = rhs.copy()
            delta[discs] = fact.solve(rhs[discs].ravel()).reshape(-1, 2)
        it += 1
        if forced is None and np.abs(delta).max() <= 1e-2 * atol:
            # the Newton step is at round-off: phi(.; lam) is minimised, update lam
            lam = update(lam, z, act)
            continue
        w = C.matvec(delta)
        alpha = 1.0 if forced is not None else _line_search(v, U, delta, z, w, rho)
        forced = None
        if alpha <= 0.0:  # no descent left at round-off level: refactor exactly
            fact_act = None
            continue
        v = v + alpha * delta
        r2n = r2 - alpha * w  # incremental: d - B v_new
        zn = lam - rho * r2n
        new_act = zn > 0
        if alpha == 1.0 and not np.any((new_act != act) & (np.abs(zn) > eta)):
            # v minimises phi(.; lam) on this piece: multiplier update
            lam = update(lam, zn, act)
    return ProjectionResult(v, lam, it, nfact, float(kkt), converged, "exact")


# --------------------------------------------------------------------------
# Uzawa (seed 000 eq. 17)
# --------------------------------------------------------------------------


def _uzawa(C: Constraints, U, d, lam, atol, max_iter, nu):
    if C.m == 0:
        return ProjectionResult(U.copy(), lam, 0, 0, 0.0, True, "uzawa")
    if nu is None:
        nu = 1.9 / C.norm2_bound()  # 0 < nu < 2 / ||B||^2
    # work with the dual operator M = B B^T as a sparse matrix: one mat-vec per sweep
    B = C.to_csr()
    M = (B @ B.T).tocsr()
    c = B @ U.ravel() - d  # B u - d = c - M lam  for u = U - B^T lam
    it = 0
    converged = False
    check = 10
    while it < max_iter:
        for _ in range(check):
            res = c - M @ lam  # = B u^{k+1} - d with u^{k+1} = U - B^T lam^k
            lam = np.maximum(lam + nu * res, 0.0)
        it += check
        res = c - M @ lam
        if np.abs(np.minimum(lam, -res)).max() <= atol * 1e-2:
            u = U - C.rmatvec(lam)
            if kkt_residual(C, U, d, u, lam) <= atol:
                converged = True
                break
    u = U - C.rmatvec(lam)
    kkt = kkt_residual(C, U, d, u, lam)
    return ProjectionResult(u, lam, it, 0, kkt, converged, "uzawa")
