"""Cost of a bordered solve against a new numeric factorisation (the choice of linear.BORDER_MAX),
and of the factorisation in CHOLMOD's own order against the nested-dissection order of Projection.

On the benchmark hall of scale.py, S_0 = the cells within R of the door is factorised
(EnvelopeCholesky) in both orders; then, in the nested-dissection order, S = S_0 plus k cells
of its neighbour layer is solved by bordering the kept factor, for k = 1 ... 32, and timed
against one numeric factorisation plus a solve.

    python benchmarks/bordering.py                    # 1e5 and 1e6 triangles, R = 7 m
    python benchmarks/bordering.py --sizes 1e5 --radius 5
"""

import argparse
import time

import numpy as np
from scale import mesh_file


def one_size(target, radius):
    from femcrowd.linalg.envelope import EnvelopeCholesky
    from femcrowd.macro.projection import Projection
    from femcrowd.mesh import Boundary, load_domain

    domain = load_domain(mesh_file(target), ["exit"])
    projection = Projection(domain, Boundary(domain).at(0.0))
    A = projection.A
    c = domain.centroid
    S0 = np.flatnonzero((c[:, 0] - 20) ** 2 + (c[:, 1] - 7.5) ** 2 < radius ** 2)
    envelope = np.flatnonzero((c[:, 0] - 20) ** 2 + (c[:, 1] - 7.5) ** 2 < (radius + 0.5) ** 2)
    tic = time.perf_counter()
    order = projection.solver.nested_dissection()
    metis = time.perf_counter() - tic
    for label, rank in (("CHOLMOD's own order (AMD)", None), ("nested dissection of the mesh (METIS)", order)):
        tic = time.perf_counter()
        factor = EnvelopeCholesky(A, envelope, len(S0), rank)
        symbolic = time.perf_counter() - tic
        tic = time.perf_counter()
        factor.prepare(S0)
        numeric = time.perf_counter() - tic
        print(f"{label}: symbolic analysis {1e3 * symbolic:.1f} ms, numeric factorisation {1e3 * numeric:.1f} ms")
    print(f"METIS order of the {domain.ncells} cells (once): {metis:.2f} s; bordering below in that order")
    tic = time.perf_counter()
    factor.solve(S0, domain.area[S0])
    solve = time.perf_counter() - tic
    print(f"{domain.ncells} triangles, |S_0| = {len(S0)}: numeric factorisation {1e3 * numeric:.1f} ms, "
          f"solve {1e3 * solve:.1f} ms")
    front = np.setdiff1d(A[S0].indices, S0)
    for k in (1, 2, 4, 8, 16, 32):
        S = np.union1d(S0, front[:: max(1, len(front) // k)][:k])
        tic = time.perf_counter()
        factor.solve(S, domain.area[S])  # bordered for any k: prepare() (which applies BORDER_MAX) is not called
        bordered = time.perf_counter() - tic
        print(f"  k = {k:2d}: bordered solve {1e3 * bordered:7.1f} ms = {bordered / (numeric + solve):.2f} x "
              f"(factorisation + solve)")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e5, 1e6])
    parser.add_argument("--radius", type=float, default=7.0, help="radius of S_0 around the door [m]")
    args = parser.parse_args()
    for target in args.sizes:
        one_size(target, args.radius)


if __name__ == "__main__":
    main()
