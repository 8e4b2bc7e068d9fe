"""The actual velocity u = U - grad p (macro/reconstruction.py): the RT0 cell means of the scheme's fluxes,
exact for a constant field, and the same on a few cells (measurement areas) as on the whole mesh."""

import numpy as np

from femcrowd.macro.reconstruction import CellMean

from ..support import unit_square


def test_cell_means_of_a_constant_field_are_exact():
    """The RT0 interpolant of a constant field is the field: its cell means give it back to round-off."""
    domain = unit_square(8)
    U = np.array([0.7, -0.4])
    G = domain.normal @ U * domain.length    # the fluxes k0 -> k1 of U (outward on the boundary)
    np.testing.assert_allclose(CellMean(domain)(G), np.tile(U, (domain.ncells, 1)), atol=1e-14)


def test_a_few_cells_from_their_facets_alone():
    """On a subset of cells (out of order) the means read only the subset's facets and equal
    the whole mesh's, for a field discontinuous across facets (G seen from f2t[0], G1 from f2t[1])."""
    domain = unit_square(8)
    rng = np.random.default_rng(1)
    G, G1 = rng.normal(size=(2, len(domain.length)))
    cells = np.array([7, 3, 100, 0, domain.ncells - 1])
    few = CellMean(domain, cells)
    assert len(few.facets) <= 3 * len(cells) < len(domain.length)
    np.testing.assert_allclose(few(G[few.facets], G1[few.facets]), CellMean(domain)(G, G1)[cells], rtol=1e-13,
                               atol=1e-14)
