"""CHOLMOD's update/downdate of the envelope factorisation (Davis, Hager 2001; scikit-sparse) against a new
numeric factorisation (cvxopt's supernodal CHOLMOD, the projection's), as a function of the number k of cells
that join or leave the saturated set S (docs/performance.md, "Update/downdate instead of a new factor").

K = T A_EE T + diag(A_EE)(I - T), T = diag(1_S) (femcrowd/linalg/envelope.py) holds the off-diagonal entry
a = A_ij exactly when i and j are both in S. When S changes, each entry that appears (sigma = +1) or vanishes
(sigma = -1) is, with s = sign(a),

    sigma a (e_i e_j^T + e_j e_i^T) = |a| u u^T - |a| (e_i e_i^T + e_j e_j^T),   u = e_i + sigma s e_j:

one update column sqrt|a| u per entry, then one downdate column sqrt(d_k) e_k per cell touched (d_k the sum of
the |a| of its changed entries); the update first, so every intermediate matrix is positive definite.

On the benchmark hall of scale.py, S_0 = the cells within R of the door and its envelope (S_0 and 8 layers, as
the projection builds it) in the nested-dissection order of the mesh. S = S_0 without k cells of its far end
(the draining queue) or with k cells of its neighbour layer (the growing queue, at most the layer) is solved
(a) by a new numeric factorisation of K and a solve (EnvelopeCholesky, as the projection does), (b) by
updating a kept simplicial L D L^T of K(S_0) and a solve. Alternated, CPU seconds, medians of --repeat rounds;
the two solutions are compared. Needs scikit-sparse 0.4 (``pip install "scikit-sparse<0.5"`` after
``apt-get install libsuitesparse-dev``; 0.5 needs SuiteSparse 7).

    python benchmarks/updown.py --sizes 2.5e5 --radius 10
"""

import argparse
import time

import numpy as np
import scipy.sparse as sp
from scale import mesh_file


class UpdatableCholesky:
    """L D L^T = K(S) (simplicial, in the given order) for every S inside a fixed envelope E, changed in place
    by update/downdate from one S to the next."""

    def __init__(self, A, envelope, rank):
        from sksparse.cholmod import analyze

        from femcrowd.linalg.cholmod import lower_pattern

        local = np.argsort(np.argsort(rank[envelope]))
        self.position = np.full(A.shape[0], -1, np.intp)   # position of a cell in the factor (-1: not in E)
        self.position[envelope] = local
        inverse = np.argsort(local)
        self.row, self.col, self.values = lower_pattern(A[envelope][:, envelope][inverse][:, inverse])
        self.off = self.row != self.col
        self.shape = (len(envelope),) * 2
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(self.col, minlength=len(envelope)))])
        # the order is applied to K above; scikit-sparse 0.4 takes no order of its own, and CHOLMOD does not
        # postorder a "natural" one, so a supernodal factor in it has small supernodes (slow): simplicial
        self.factor = analyze(self._lower(self.values), mode="simplicial", ordering_method="natural")
        self.mask = np.zeros(len(envelope), bool)         # S in factor positions

    def _lower(self, values):
        """The lower triangle of K with these values, every entry of the pattern kept (zeros too)."""
        return sp.csc_matrix((values, self.row, self.indptr), shape=self.shape)

    def factorise(self, cells):
        """A new numeric factorisation of K for S = cells."""
        self.mask[:] = False
        self.mask[self.position[cells]] = True
        keep = ~self.off | (self.mask[self.row] & self.mask[self.col])
        self.factor.cholesky_inplace(self._lower(np.where(keep, self.values, 0.0)))

    def change(self, cells):
        """The factor of K for S = cells, updated from the factor of the last S (cells inside E)."""
        mask = np.zeros_like(self.mask)
        mask[self.position[cells]] = True
        before = self.mask[self.row] & self.mask[self.col]
        after = mask[self.row] & mask[self.col]
        changed = np.flatnonzero(self.off & (before != after))
        self.mask = mask
        i, j, a = self.row[changed], self.col[changed], self.values[changed]
        root, m, n = np.sqrt(np.abs(a)), len(changed), self.shape[0]
        sign = np.where(after[changed], 1.0, -1.0) * np.sign(a)
        rows = np.stack([j, i], axis=1).ravel()             # j < i: each column's rows sorted
        update = sp.csc_matrix((np.stack([sign * root, root], axis=1).ravel(), rows, np.arange(0, 2 * m + 1, 2)),
                               shape=(n, m))
        d = np.bincount(i, np.abs(a), n) + np.bincount(j, np.abs(a), n)
        touched = np.flatnonzero(d)
        downdate = sp.csc_matrix((np.sqrt(d[touched]), touched, np.arange(len(touched) + 1)),
                                 shape=(n, len(touched)))
        self.factor.update_inplace(update)
        self.factor.update_inplace(downdate, subtract=True)

    def solve(self, cells, rhs):
        """x on S = cells (the S of the factor) with A_SS x = rhs."""
        b = np.zeros(self.shape[0])
        at = self.position[cells]
        b[at] = rhs
        return self.factor.solve_A(b)[at]


def cpu(function):
    tic = time.process_time()
    value = function()
    return time.process_time() - tic, value


def one_size(target, radius, repeat, counts):
    from femcrowd.linalg.envelope import EnvelopeCholesky
    from femcrowd.macro.projection import Projection
    from femcrowd.mesh import Boundary, load_domain

    domain = load_domain(mesh_file(target), ["exit"])
    projection = Projection(domain, Boundary(domain).at(0.0))
    A, solver = projection.A, projection.solver
    c = domain.centroid
    distance = np.hypot(c[:, 0] - 20, c[:, 1] - 7.5)
    S0 = np.flatnonzero(distance < radius)
    envelope = solver.envelope(S0)
    rank = solver.nested_dissection()
    supernodal = EnvelopeCholesky(A, envelope, len(S0), rank)
    t_analyse, updatable = cpu(lambda: UpdatableCholesky(A, envelope, rank))
    t_simplicial, _ = cpu(lambda: updatable.factorise(S0))
    t_super, _ = cpu(lambda: supernodal.prepare(S0))
    print(f"{domain.ncells} triangles, |S_0| = {len(S0)}, |E| = {len(envelope)}, CPU s: supernodal numeric "
          f"(cvxopt) {t_super:.3f}; simplicial (scikit-sparse) analysis {t_analyse:.3f}, numeric {t_simplicial:.3f}",
          flush=True)
    front = np.setdiff1d(A[S0].indices, S0)
    front = front[np.argsort(distance[front])]
    rear = S0[np.argsort(-distance[S0])]          # the far end of S first
    for label, change in (("leave", lambda k: np.setdiff1d(S0, rear[:k])),
                          ("join", lambda k: np.union1d(S0, front[:: max(1, len(front) // k)][:k]))):
        for k in counts:
            S = change(k)
            rhs = domain.area[S]
            fresh, updated, error = [], [], 0.0
            for _ in range(repeat):
                supernodal.prepare(S0)
                t_fresh, x = cpu(lambda: (supernodal.prepare(S), supernodal.solve(S, rhs))[1])
                updatable.factorise(S0)
                t_updated, y = cpu(lambda: (updatable.change(S), updatable.solve(S, rhs))[1])
                fresh.append(t_fresh)
                updated.append(t_updated)
                error = max(error, float(np.abs(x - y).max() / np.abs(x).max()))
            f, u = np.median(fresh), np.median(updated)
            print(f"  {label} k = {abs(len(S) - len(S0)):5d}: factorise + solve {f:.3f} s, update + solve {u:.3f} s, "
                  f"ratio {u / f:.2f}, relative difference {error:.1e}", flush=True)


def main():
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        raise SystemExit('benchmarks/updown.py needs scikit-sparse 0.4: apt-get install libsuitesparse-dev, then '
                         'pip install "scikit-sparse<0.5"')
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[2.5e5])
    parser.add_argument("--radius", type=float, default=10.0, help="radius of S_0 around the door [m]")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--counts", type=int, nargs="+", default=[8, 32, 128, 512, 2048])
    args = parser.parse_args()
    for target in args.sizes:
        one_size(target, args.radius, args.repeat, args.counts)


if __name__ == "__main__":
    main()
