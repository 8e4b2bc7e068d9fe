"""The P1 gradient per triangle (femcrowd.mesh.triangles.P1Gradient, Domain.gradient): exact for linear fields."""

import numpy as np
from scipy.spatial import Delaunay

from femcrowd.mesh.triangles import P1Gradient


def test_the_gradient_of_a_linear_field_is_exact_in_every_cell_and_inf_next_to_an_unreached_node():
    rng = np.random.default_rng(3)
    p = rng.random((60, 2)) * [4.0, 2.0]
    t = Delaunay(p).simplices
    gradient = P1Gradient(p, t)
    d = 0.7 - 1.5 * p[:, 0] + 2.25 * p[:, 1]
    np.testing.assert_allclose(gradient(d), np.tile([-1.5, 2.25], (len(t), 1)), rtol=0, atol=1e-12)
    cells = np.array([5, 0, 17])
    np.testing.assert_array_equal(gradient(d, cells), gradient(d)[cells])
    d[t[4, 1]] = np.inf   # a node no exit reaches: the gradient of its cells is inf, of the others exact
    g = gradient(d)
    touches = np.isinf(d[t]).any(axis=1)
    assert touches[4] and np.all(np.isinf(g[touches]))
    np.testing.assert_allclose(g[~touches], np.tile([-1.5, 2.25], ((~touches).sum(), 1)), rtol=0, atol=1e-12)
