"""Distance to the exits (femcrowd.mesh.distance.exit_distance) against exact distances.

Exact solutions used:
- disc of radius R at the origin in the square [-L, L]^2, exit = the whole side x = -L:
  d = x + L where the path to the left is free, else tangent segment + arc to the top (or
  bottom) of the disc + L (taut string);
- door y in [-a, a] on the side x = -L of an empty square: distance to that segment;
- L-shaped room (reflex corner at (1, 1)), exit on top of the left arm: 2 - y for x <= 1,
  else 1 + |P - (1, 1)| (the path wraps around the corner).
Meshes come from gmsh (unstructured, Delaunay) or from a structured grid.
"""

import warnings

import gmsh
import numpy as np
import pytest

from femcrowd.mesh import distance
from femcrowd.mesh.distance import exit_distance

R, L = 0.5, 2.0


# ----------------------------------------------------------------------------- helpers


def gmsh_mesh(build, h, algorithm=6, smoothing=1):
    """Mesh the surface(s) made by build(occ) with size h (gmsh's Mesh.Algorithm and
    Mesh.Smoothing: frontal-Delaunay, one smoothing pass by default); return points, triangles."""
    own = not gmsh.isInitialized()
    if own:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("test_distance")
        build(gmsh.model.occ)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm", algorithm)
        gmsh.option.setNumber("Mesh.Smoothing", smoothing)
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, conn = gmsh.model.mesh.getElementsByType(2)
        gmsh.model.remove()
    finally:
        if own:
            gmsh.finalize()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    t = index[conn.astype(np.int64).reshape(-1, 3)]
    used = np.unique(t)
    renum = np.full(len(tags), -1)
    renum[used] = np.arange(len(used))
    return xyz.reshape(-1, 3)[used, :2].copy(), renum[t]


def boundary_edges(t):
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    u, c = np.unique(e, axis=0, return_counts=True)
    return u[c == 1]


def edges_where(p, t, pred):
    """Boundary edges whose two end points satisfy pred(x, y)."""
    b = boundary_edges(t)
    return b[pred(*p[b[:, 0]].T) & pred(*p[b[:, 1]].T)]


def disc_mesh(h, **options):
    """Square [-L, L]^2 minus the disc of radius R; exit edges on x = -L (options: see gmsh_mesh)."""

    def build(occ):
        occ.cut([(2, occ.addRectangle(-L, -L, 0, 2 * L, 2 * L))], [(2, occ.addDisk(0, 0, 0, R, R))])

    p, t = gmsh_mesh(build, h, **options)
    return p, t, edges_where(p, t, lambda x, y: np.abs(x + L) < 1e-9)


def disc_exact(x, y):
    """Exact distance to the side x = -L behind the disc, and its unit gradient."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    d = x + L
    g = np.zeros(x.shape + (2,))
    g[..., 0] = 1.0
    hidden = (np.abs(y) < R) & (x > 0)
    xs, ys = x[hidden], np.abs(y[hidden])
    r = np.hypot(xs, ys)
    alpha = np.arccos(np.minimum(R / r, 1.0))  # angle between OP and the tangent point OT
    theta = np.arctan2(ys, xs)
    d[hidden] = np.sqrt(np.maximum(r * r - R * R, 0.0)) + R * (np.pi / 2 - theta - alpha) + L
    phi = theta + alpha  # polar angle of the tangent point (upper half, mirrored below)
    sgn = np.where(y[hidden] >= 0, 1.0, -1.0)
    tx, ty = R * np.cos(phi), sgn * R * np.sin(phi)
    v = np.stack([xs - tx, sgn * ys - ty], axis=-1)
    nv = np.linalg.norm(v, axis=-1, keepdims=True)
    tangent = np.stack([np.sin(phi), -sgn * np.cos(phi)], axis=-1)  # on the disc itself
    g[hidden] = np.where(nv > 1e-12, v / np.maximum(nv, 1e-300), tangent)
    return d, g


def p1_gradient(p, t, d):
    x = p[t]
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    d1, d2 = d[t[:, 1]] - d[t[:, 0]], d[t[:, 2]] - d[t[:, 0]]
    return np.stack([(d1 * e2[:, 1] - d2 * e1[:, 1]) / det, (d2 * e1[:, 0] - d1 * e2[:, 0]) / det], axis=1)


def angle_error(p, t, d, exact_grad):
    """Angle (degrees) between the P1 gradient of d and the exact gradient at the centroid."""
    g = p1_gradient(p, t, d)
    ge = exact_grad(p[t].mean(axis=1))
    cos = np.einsum("ij,ij->i", g, ge) / np.linalg.norm(g, axis=1) / np.linalg.norm(ge, axis=1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def disc_errors(h):
    p, t, ex = disc_mesh(h)
    d = exit_distance(p, t, ex)
    de, _ = disc_exact(*p.T)
    err = np.abs(d - de)
    ang = angle_error(p, t, d, lambda c: disc_exact(*c.T)[1])
    c = p[t].mean(axis=1)
    # the cut locus y = 0 behind the disc, where grad d jumps, is left out of the angle error
    away = ~((c[:, 0] > 0) & (np.abs(c[:, 1]) < 2 * h))
    return dict(h=h, p=p, t=t, ex=ex, d=d, max=err.max(), mean=err.mean(),
                ang_max=ang[away].max(), ang_mean=ang[away].mean())


def grid(x0, x1, y0, y1, nx, ny, offset=0):
    x, y = np.meshgrid(np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1), indexing="ij")
    p = np.stack([x.ravel(), y.ravel()], axis=1)
    i = np.arange(nx)[:, None] * (ny + 1) + np.arange(ny)[None, :]
    i = i.ravel()
    t = np.concatenate([np.stack([i, i + ny + 1, i + ny + 2], 1), np.stack([i, i + ny + 2, i + 1], 1)])
    return p, t + offset


def rate(hs, errs):
    return np.polyfit(np.log(hs), np.log(errs), 1)[0]


# ----------------------------------------------------------------------------- tests


@pytest.fixture(scope="module")
def disc_study():
    return [disc_errors(h) for h in (0.1, 0.05, 0.025)]


def test_disc_obstacle_accuracy_and_convergence(disc_study):
    hs = np.array([s["h"] for s in disc_study])
    mx = np.array([s["max"] for s in disc_study])
    mean = np.array([s["mean"] for s in disc_study])
    # measured: max 0.27 h, 0.27 h, 0.32 h; mean 0.017 h, 0.020 h, 0.019 h; rates 0.86, 0.90
    assert np.all(mx <= 0.45 * hs), mx / hs
    assert np.all(mean <= 0.03 * hs), mean / hs
    assert rate(hs, mx) > 0.6
    assert rate(hs, mean) > 0.6
    assert np.all(np.diff(mx) < 0) and np.all(np.diff(mean) < 0)


def test_disc_obstacle_gradient_direction(disc_study):
    # measured: max 7.6, 8.2, 6.7 degrees (at the disc and at the edge of the shadow);
    # mean 0.26, 0.18, 0.10 degrees (rate 0.70)
    for s in disc_study:
        assert s["ang_max"] < 12.0
    means = [s["ang_mean"] for s in disc_study]
    assert means[-1] < 0.15
    assert rate([s["h"] for s in disc_study], means) > 0.6


def test_exact_where_the_exit_is_in_sight(disc_study):
    # Left of the disc the paths are straight horizontal lines: the scheme is exact for a
    # linear d (up to the iteration tolerance, 1e-6 of an edge), and the seeding measures the
    # distance to the exit segments, not to their nodes (that would be off by ~0.1 h).
    for s in disc_study:
        p, d = s["p"], s["d"]
        left = p[:, 0] < -R - 0.1
        np.testing.assert_allclose(d[left], p[left, 0] + L, rtol=0, atol=1e-5 * s["h"])


def test_zero_on_the_exit_and_positive_inside(disc_study):
    s = disc_study[0]
    on_exit = np.unique(s["ex"])
    assert np.all(s["d"][on_exit] == 0.0)
    rest = np.setdiff1d(np.arange(len(s["p"])), on_exit)
    assert np.all(s["d"][rest] > 0) and np.all(np.isfinite(s["d"]))


def test_band_keeps_the_fixed_point(monkeypatch):
    # gmsh's Delaunay without smoothing leaves obtuse triangles (here 12 % of them, up to 119
    # degrees), where relaxing every active node (an infinite band) made each corner update ~24
    # times on the 10^6-triangle hall. Relaxing only the band near the front must reach the same
    # fixed point: with a zero stopping tolerance the two orders agree to round-off.
    h = 0.05
    p, t, ex = disc_mesh(h, algorithm=5, smoothing=0)
    monkeypatch.setattr(distance, "REL_TOL", 0.0)
    banded = exit_distance(p, t, ex)
    monkeypatch.setattr(distance, "BAND", np.inf)
    everywhere = exit_distance(p, t, ex)
    np.testing.assert_allclose(banded, everywhere, rtol=0, atol=1e-12)
    monkeypatch.undo()
    d = exit_distance(p, t, ex)  # measured: 2e-6 h from that fixed point with the default tolerance
    np.testing.assert_allclose(d, banded, rtol=0, atol=1e-5 * h)
    err = np.abs(d - disc_exact(*p.T)[0])  # measured: max 0.24 h, mean 0.017 h
    assert err.max() <= 0.45 * h and err.mean() <= 0.03 * h, (err.max() / h, err.mean() / h)


def test_door_segment_endpoints():
    # door |y| <= 0.5 on the side x = -2: the distance to a segment, radial past its ends
    a = 0.5

    def build(occ):
        pts = [occ.addPoint(*xy, 0) for xy in [(-L, -L), (L, -L), (L, L), (-L, L), (-L, a), (-L, -a)]]
        lines = [occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
        occ.addPlaneSurface([occ.addCurveLoop(lines)])

    errs = []
    hs = (0.2, 0.1, 0.05)
    for h in hs:
        p, t = gmsh_mesh(build, h)
        ex = edges_where(p, t, lambda x, y: (np.abs(x + L) < 1e-9) & (np.abs(y) <= a + 1e-9))
        d = exit_distance(p, t, ex)
        de = np.hypot(p[:, 0] + L, np.maximum(np.abs(p[:, 1]) - a, 0.0))
        errs.append(np.abs(d - de).max())
        # right in front of the door the paths are straight and parallel: exact
        in_front = (np.abs(p[:, 1]) < a / 2) & (p[:, 0] < -L + 0.25)
        np.testing.assert_allclose(d[in_front], de[in_front], atol=1e-5 * h)
    # measured: 0.29 h, 0.40 h, 0.49 h (0.62 h at h = 0.0125), on the far walls: past the door
    # ends d is the distance to a point, for which fast marching schemes have an
    # O(h log(1/h)) error; the rate over these three meshes is 0.63
    assert np.all(np.array(errs) <= 0.7 * np.array(hs)), errs
    assert rate(hs, errs) > 0.5


def test_reflex_corner():
    # L-shaped room [0,2]^2 minus [1,2]x[1,2], exit y = 2, 0 <= x <= 1; paths wrap around (1, 1)
    def build(occ):
        occ.cut([(2, occ.addRectangle(0, 0, 0, 2, 2))], [(2, occ.addRectangle(1, 1, 0, 1, 1))])

    errs, angs = [], []
    hs = (0.1, 0.05, 0.025)
    for h in hs:
        p, t = gmsh_mesh(build, h)
        ex = edges_where(p, t, lambda x, y: (np.abs(y - 2) < 1e-9) & (x <= 1 + 1e-9))
        d = exit_distance(p, t, ex)
        x, y = p.T
        de = np.where(x <= 1, 2 - y, 1 + np.hypot(x - 1, y - 1))
        errs.append(np.abs(d - de).max())

        def grad(c):
            v = c - 1.0
            nv = np.linalg.norm(v, axis=1, keepdims=True)
            return np.where(c[:, :1] <= 1, [[0.0, -1.0]], v / nv)

        c = p[t].mean(axis=1)
        near = np.hypot(c[:, 0] - 1, c[:, 1] - 1) < 2 * h  # grad d is singular at the corner
        angs.append(angle_error(p, t, d, grad)[~near].max())
        # no shortcut through the wall: the computed d is never below the exact one
        assert (d - de).min() > -1e-9
    # measured: max error 0.31 h, 0.37 h, 0.49 h (past the corner d is the distance to a point,
    # O(h log(1/h)) for fast marching schemes), rate 0.66; angle max 12 degrees, on the walls
    # that the rays from the corner graze; mean 1.5, 0.6, 0.6 degrees
    assert np.all(np.array(errs) <= 0.6 * np.array(hs)), errs
    assert rate(hs, errs) > 0.5
    assert max(angs) < 15.0, angs


def test_two_exits_take_the_nearest():
    p, t = grid(-L, L, -1, 1, 40, 20)
    left = edges_where(p, t, lambda x, y: np.abs(x + L) < 1e-9)
    right = edges_where(p, t, lambda x, y: np.abs(x - L) < 1e-9)
    dl = exit_distance(p, t, left)
    dr = exit_distance(p, t, right)
    both = exit_distance(p, t, np.concatenate([left, right]))
    np.testing.assert_allclose(dl, p[:, 0] + L, atol=1e-12)
    np.testing.assert_allclose(dr, L - p[:, 0], atol=1e-12)
    h = 2 * L / 40
    # exact away from the ridge x = 0 where the two fronts meet; O(h) there
    far = np.abs(p[:, 0]) > 2 * h
    np.testing.assert_allclose(both[far], np.minimum(dl, dr)[far], atol=1e-12)
    assert np.abs(both - np.minimum(dl, dr)).max() <= 0.5 * h
    assert np.all(both <= np.minimum(dl, dr) + 1e-12)


def test_several_exits_solved_together_are_the_solves_one_by_one():
    """Eikonal.solve_each (the route choice's doors without a capacity, each with its own band) gives the fields of
    separate solves to the last bit, with a cost that varies per triangle and with an exit cut off from nothing."""
    p, t, ex = disc_mesh(0.1)
    left = ex
    right = edges_where(p, t, lambda x, y: np.abs(x - L) < 1e-9)
    top = edges_where(p, t, lambda x, y: (np.abs(y - L) < 1e-9) & (x > 1))
    centroid = p[t].mean(axis=1)
    cost = 1.0 + 4.0 * np.exp(-4 * ((centroid[:, 0] - 1) ** 2 + centroid[:, 1] ** 2))   # a jam right of the disc
    solver = distance.Eikonal(p, t)
    for c in (None, cost):
        together = solver.solve_each([left, right, top], c)
        assert together.shape == (3, len(p))
        for d, edges in zip(together, [left, right, top]):
            assert np.array_equal(d, distance.Eikonal(p, t).solve(edges, c))
    assert solver.solve_each([], cost).shape == (0, len(p))


def test_each_node_updates_from_its_corners_and_wakes_the_corners_that_read_it():
    """The padded tables of the iteration: the row of node v holds the corners whose node C is v (own) and those
    whose A or B is v (read), each once, the rest the empty corner; in a tiled copy j the same shifted by j."""
    p, t, _ = disc_mesh(0.2, algorithm=5, smoothing=0)
    corners = distance._Corners(p, t)
    empty = 3 * len(t)
    C, A, B = t.ravel(), np.roll(t, -1, axis=1).ravel(), np.roll(t, -2, axis=1).ravel()
    for copies, tables in ((1, corners), (3, corners.tiled(3))):
        assert tables.own.shape[0] == copies * len(p) and tables.empty == copies * empty
        for v in range(0, copies * len(p), 7):
            j, node = divmod(v, len(p))
            own, read = tables.own[v], tables.read[v]
            own, read = own[own != copies * empty], read[read != copies * empty]
            assert sorted(own) == sorted(j * empty + np.flatnonzero(C == node))
            assert sorted(read) == sorted(j * empty + np.flatnonzero((A == node) | (B == node)))
            assert np.all(tables.C[own] == v)
            assert np.all((tables.AB[0, read] == v) | (tables.AB[1, read] == v))


def test_cut_off_component_is_inf_without_warnings():
    p1, t1 = grid(0, 1, 0, 1, 8, 8)
    p2, t2 = grid(3, 4, 0, 1, 8, 8, offset=len(p1))
    p, t = np.concatenate([p1, p2]), np.concatenate([t1, t2])
    ex = edges_where(p, t, lambda x, y: np.abs(x) < 1e-9)
    lonely = np.array([[10.0, 10.0]])  # a node in no triangle
    p = np.concatenate([p, lonely])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = exit_distance(p, t, ex)
    assert not np.isnan(d).any()
    np.testing.assert_allclose(d[: len(p1)], p1[:, 0], atol=1e-12)
    assert np.all(np.isinf(d[len(p1):]))


def test_no_exit_and_bad_input():
    p, t = grid(0, 1, 0, 1, 4, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.all(np.isinf(exit_distance(p, t, np.zeros((0, 2), int))))
    with pytest.raises(ValueError):
        exit_distance(p, t, [[0, len(p)]])
    with pytest.raises(ValueError):
        exit_distance(p[:, :1], t, [[0, 1]])
