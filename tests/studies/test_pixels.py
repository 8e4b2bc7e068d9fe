"""Pixel averages of the `l1_pixels` metric: exact for cell-wise fields, conservative, and converging at
second order on exact cell averages of the radial solution (the midpoint rule it replaces did not)."""

import math

import numpy as np
import pytest
import skfem

from femcrowd.case import load_case
from femcrowd.mesh import load_domain
from femcrowd.studies.measures import PIXELS, ExactReference, Pixels, _pixel_l1, exact_solution

from ..support import CASES

LINES = np.linspace(-1.0, 1.0, 38)   # 37 divisions: the mesh lines are not pixel lines (0.04 apart)


def square(cut=None):
    """Triangles of [-1, 1]^2 on LINES, jittered inside; without the cells right of and above `cut`."""
    mesh = skfem.MeshTri.init_tensor(LINES, LINES)
    p, t = mesh.p.T.copy(), mesh.t.T
    inner = np.all(np.abs(p) < 1 - 1e-12, axis=1) & ~np.isin(p[:, 0], LINES[[10, 20]])
    p[inner, 1] += np.random.default_rng(0).uniform(-0.01, 0.01, inner.sum())   # y only: x-lines stay
    if cut is not None:
        c = p[t].mean(1)
        t = t[~((c[:, 0] > cut) & (c[:, 1] > cut))]
    return p, t


def column_fraction(edge):
    """Area fraction left of x = edge in each pixel column of [-1, 1]."""
    left = -1 + 2 * np.arange(PIXELS) / PIXELS
    return np.clip((edge - left) / (2 / PIXELS), 0, 1)


def test_a_cellwise_half_plane_is_averaged_exactly():
    p, t = square()
    edge = LINES[10]
    values = (p[t][:, :, 0].mean(1) < edge).astype(float)
    averages = Pixels(p, t).of_cells(values).reshape(PIXELS, PIXELS)
    assert np.abs(averages - column_fraction(edge)[:, None]).max() < 1e-12


def test_mass_is_kept_and_outside_counts_zero():
    p, t = square(cut=LINES[20])
    pixels = Pixels(p, t)
    values = np.random.default_rng(1).uniform(0, 1, len(t))
    e1, e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert pixels.area * pixels.of_cells(values).sum() == pytest.approx(area @ values, rel=1e-13)
    # a function equal to 1 is averaged to the covered fraction, the pixels astride the hole to 1/64
    ones = pixels.of_function(lambda x, y, s: np.ones_like(x), 0.0)
    assert np.abs(ones - pixels.covered).max() <= 1 / 64 + 1e-12
    assert np.abs(ones - pixels.of_cells(np.ones(len(t)))).max() <= 1 / 64 + 1e-12
    hole = (column_fraction(LINES[20])[:, None] < 1e-12) & (column_fraction(LINES[20])[None, :] < 1e-12)
    assert np.all(ones.reshape(PIXELS, PIXELS)[hole] == 0.0)


def test_exact_cell_averages_of_the_radial_solution_converge_at_second_order():
    case = load_case(CASES / "radial")
    reference = ExactReference(exact_solution(case))
    errors, sizes = [], []
    for level in (1, 2, 3):
        domain = load_domain(case.path(case["mesh"]["file"]), refine=level)
        averages = domain.cell_average(reference.density, t=0.4)
        errors.append(_pixel_l1(domain, averages, reference, 0.4))
        sizes.append(domain.h)
    orders = [math.log(errors[i] / errors[i + 1]) / math.log(sizes[i] / sizes[i + 1]) for i in range(2)]
    assert min(orders) > 1.5, (errors, orders)
