"""The one place where the size of a triangle is computed."""

import numpy as np


def doubled_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(b - a) x (c - a) for the triangles (a, b, c): twice the signed area (> 0 counter-clockwise)."""
    a, b, c = (points[triangles[:, k], :2] for k in range(3))
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
