"""Distance to the exits: time and error of femcrowd.mesh.distance.exit_distance per mesh size.

    python benchmarks/distance.py              # ~1e4, 1e5, 1e6 triangles
    python benchmarks/distance.py --quick      # ~1e4, 1e5 triangles
    python benchmarks/distance.py --compare    # also the libraries that are installed:
                                               # potpourri3d, fim-python, pygeodesic, scikit-fmm
    python benchmarks/distance.py --cache DIR  # keep the gmsh meshes (1e6 triangles: ~35 s)

Test case (exact solution in tests/test_distance.py): the square [-2, 2]^2 minus the disc of
radius 0.5 at the origin, meshed by gmsh, exit = the whole side x = -2. Errors: nodal |d - d_exact|
(max, mean) and the angle between the P1 gradient of d and the exact gradient per triangle
(max, 99th percentile, mean; triangles within 2 h of the cut locus y = 0 behind the disc, where
grad d jumps, are left out). The rate is the observed order between consecutive meshes.
Times: wall clock and CPU time of the process (the two differ when other jobs load the machine).
"""

import argparse
import contextlib
import importlib.util
import io
import os
import sys
import time
from pathlib import Path

# One BLAS thread: fim-python's batched small matrix products otherwise spin threads that,
# on a loaded 2-core machine, made it 10 to 100 times slower (measured). femcrowd uses no BLAS.
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from femcrowd.mesh.distance import _seed_values, exit_distance  # noqa: E402

_spec = importlib.util.spec_from_file_location("_test_distance", ROOT / "tests" / "mesh" / "test_distance.py")
T = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(T)


def errors(p, t, d, h):
    de, _ = T.disc_exact(*p.T)
    err = np.abs(d - de)
    ang = T.angle_error(p, t, d, lambda c: T.disc_exact(*c.T)[1])
    c = p[t].mean(axis=1)
    away = ~((c[:, 0] > 0) & (np.abs(c[:, 1]) < 2 * h)) & np.isfinite(ang)
    return dict(max=err.max(), mean=err.mean(), ang_max=ang[away].max(),
                ang_p99=np.percentile(ang[away], 99), ang_mean=ang[away].mean())


def timed(f, *a):
    w, c = time.perf_counter(), time.process_time()
    out = f(*a)
    return out, time.perf_counter() - w, time.process_time() - c


def mesh(h, cache):
    if cache is None:
        return T.disc_mesh(h)
    f = cache / f"disc_in_square_h{h:g}.npz"
    if f.exists():
        z = np.load(f)
        return z["p"], z["t"], z["ex"]
    p, t, ex = T.disc_mesh(h)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(f, p=p, t=t, ex=ex)
    return p, t, ex


# ---------------------------------------------------------------- libraries, for --compare


def _exact_seeds(p, t, ex):
    d = np.full(len(p), np.inf)
    exn = np.unique(ex)
    d[exn] = 0.0
    d = _seed_values(p, t, d, exn, ex)
    s = np.flatnonzero(np.isfinite(d))
    return s, d[s]


def lib_potpourri3d_fmm(p, t, ex):
    import potpourri3d as pp3d

    s, v = _exact_seeds(p, t, ex)  # exit nodes only would leave an O(h) offset (pop-order bug)
    solver = pp3d.MeshFastMarchingDistanceSolver(np.c_[p, np.zeros(len(p))], t)
    return np.asarray(solver.compute_distance([[(int(i), [])] for i in s], [[float(x)] for x in v]))


def lib_potpourri3d_heat(p, t, ex):
    import potpourri3d as pp3d

    solver = pp3d.MeshHeatMethodDistanceSolver(np.c_[p, np.zeros(len(p))], t)
    return np.asarray(solver.compute_distance_multisource(list(np.unique(ex))))


def lib_fim_python(p, t, ex):
    with contextlib.redirect_stdout(io.StringIO()):  # it prints a line when cupy is missing
        from fimpy.solver import create_fim_solver
    metric = np.broadcast_to(np.eye(2), (len(t), 2, 2)).copy()
    solver = create_fim_solver(p, t, metric, precision=np.float64, device="cpu")
    s = np.unique(ex)  # its Jacobi updates need no more (and many more seeds make it slower)
    return solver.comp_fim(s, np.zeros(len(s)))


def lib_pygeodesic(p, t, ex):
    from pygeodesic import geodesic

    g = geodesic.PyGeodesicAlgorithmExact(np.c_[p, np.zeros(len(p))], t.astype(np.int32))
    return g.geodesicDistances(np.unique(ex).astype(np.int32), None)[0]


def lib_scikit_fmm(p, t, ex, R=T.R, L=T.L):
    # cartesian grid of spacing h/2 (h = mean edge), disc masked, linear interpolation to nodes
    import skfmm
    from scipy import ndimage
    from scipy.interpolate import RegularGridInterpolator

    e = np.linalg.norm(p[t[:, 1]] - p[t[:, 0]], axis=1).mean() / 2
    n = int(np.ceil(2 * L / e))
    xs = np.linspace(-L - 2 * L / n, L, n + 2)  # one column outside the exit
    ys = np.linspace(-L, L, n + 1)
    x, y = np.meshgrid(xs, ys, indexing="ij")
    mask = x**2 + y**2 < R**2
    dd = skfmm.distance(np.ma.MaskedArray(x + L, mask), dx=[xs[1] - xs[0], ys[1] - ys[0]], order=2)
    dd = np.asarray(dd.filled(np.nan))
    dd = dd[tuple(ndimage.distance_transform_edt(mask, return_distances=False, return_indices=True))]
    return RegularGridInterpolator((xs, ys), dd)(p)


LIBS = {
    "potpourri3d FMM": (lib_potpourri3d_fmm, "potpourri3d", 2e6),
    "potpourri3d heat": (lib_potpourri3d_heat, "potpourri3d", 2.5e5),
    "fim-python": (lib_fim_python, "fimpy", 2e6),
    "pygeodesic (exact)": (lib_pygeodesic, "pygeodesic", 2.5e5),
    "scikit-fmm (grid)": (lib_scikit_fmm, "skfmm", 2e6),
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the 1e6-triangle mesh")
    ap.add_argument("--compare", action="store_true", help="also time the installed libraries")
    ap.add_argument("--h", type=float, nargs="*", help="mesh sizes (default 0.059 0.0188 0.0059)")
    ap.add_argument("--cache", type=Path, help="directory where the meshes are kept between runs")
    args = ap.parse_args()
    hs = args.h or ([0.059, 0.0188] if args.quick else [0.059, 0.0188, 0.0059])

    head = f"{'method':20s} {'h':>7s} {'triangles':>9s} {'wall s':>7s} {'cpu s':>7s} " \
           f"{'max err':>9s} {'mean err':>9s} {'rate':>5s} {'ang max':>7s} {'ang p99':>7s} {'ang mean':>8s}"
    print(head)
    print("-" * len(head))
    previous = {}
    for h in hs:
        (p, t, ex), tm, _ = timed(mesh, h, args.cache)
        print(f"# h = {h}: {len(t)} triangles, {len(p)} nodes, {len(ex)} exit edges (gmsh {tm:.1f} s)")
        runs = [("femcrowd", exit_distance)]
        if args.compare:
            for name, (f, module, limit) in LIBS.items():
                if importlib.util.find_spec(module) is None:
                    print(f"{name:20s} not installed")
                elif len(t) > limit:
                    print(f"{name:20s} skipped above {limit:.0e} triangles (too slow)")
                else:
                    runs.append((name, f))
        for name, f in runs:
            d, wall, cpu = timed(f, p, t, ex)
            e = errors(p, t, np.asarray(d, dtype=float), h)
            r = ""
            if name in previous:
                h0, m0 = previous[name]
                r = f"{np.log(m0 / e['mean']) / np.log(h0 / h):5.2f}"
            previous[name] = (h, e["mean"])
            print(f"{name:20s} {h:7.4f} {len(t):9d} {wall:7.2f} {cpu:7.2f} {e['max']:9.2e} "
                  f"{e['mean']:9.2e} {r:>5s} {e['ang_max']:7.2f} {e['ang_p99']:7.2f} {e['ang_mean']:8.3f}",
                  flush=True)


if __name__ == "__main__":
    main()
