"""The density the discs make on the cells of a mesh: what the route choice of the discs sees
(``[velocity] route = "congestion"``, :class:`femcrowd.macro.velocity.CongestionVelocity`)."""

import numpy as np
from scipy.spatial import cKDTree

from .sampling import HEX_PACKING

#: the radius (m) of the circle around a cell's centroid over which the discs' density is averaged: a few
#: discs, so that one disc does not make a cell saturated
DENSITY_RADIUS = 1.0


def disc_density(centroids, q, r, radius: float = DENSITY_RADIUS) -> np.ndarray:
    """Per cell: the area of the discs whose centres lie within `radius` of its centroid over the area of that
    circle, in units of the densest packing (1: rho_max), at most 1."""
    if not len(q):
        return np.zeros(len(centroids))
    pairs = cKDTree(centroids).sparse_distance_matrix(cKDTree(q), radius, output_type="ndarray")
    covered = np.bincount(pairs["i"], weights=np.pi * r[pairs["j"]] ** 2, minlength=len(centroids))
    return np.minimum(covered / (np.pi * radius**2 * HEX_PACKING), 1.0)
