"""Which moves of points cross which segments: the discs that reach an exit in a step, the signed counts of
measurement lines (PedPy's N-t curves, Adrian et al. 2020)."""

import numpy as np


def segment_crossings(p0, p1, segments, *, ending_counts: bool = False) -> np.ndarray:
    """Signed crossings (n, E) of the moves p0 -> p1 (n, 2) through the segments a -> b (E, 2, 2): +1 from the
    left of a -> b to its right, -1 back, 0 none. A move that ends on a segment crosses it now
    (``ending_counts``: a disc that reaches an exit has left) or at its next move (PedPy's rule for lines)."""
    p0, p1 = np.asarray(p0, float).reshape(-1, 2), np.asarray(p1, float).reshape(-1, 2)
    segments = np.asarray(segments, float).reshape(-1, 2, 2)
    out = np.zeros((len(p0), len(segments)), dtype=np.int8)
    if not out.size:
        return out
    a = segments[:, 0][None]  # (1, E, 2)
    ab = (segments[:, 1] - segments[:, 0])[None]
    chunk = max(1, 1_000_000 // len(segments))   # at most 10^6 move-segment pairs at once
    for start in range(0, len(p0), chunk):
        q0, q1 = p0[start : start + chunk, None], p1[start : start + chunk, None]
        s0 = ab[..., 0] * (q0[..., 1] - a[..., 1]) - ab[..., 1] * (q0[..., 0] - a[..., 0])
        s1 = ab[..., 0] * (q1[..., 1] - a[..., 1]) - ab[..., 1] * (q1[..., 0] - a[..., 0])
        on_line = (s1 == 0) & (s0 != 0) if ending_counts else (s0 == 0) & (s1 != 0)
        cross = (s0 * s1 < 0) | on_line
        if not cross.any():
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(cross, s0 / np.where(cross, s0 - s1, 1.0), 0.0)
        x = q0 + t[..., None] * (q1 - q0)
        mu = ((x - a) * ab).sum(-1) / (ab * ab).sum(-1)
        hit = cross & (mu >= 0) & (mu <= 1)
        out[start : start + chunk] = np.where(hit, np.where(s0 != 0, np.sign(s0), -np.sign(s1)), 0)
    return out
