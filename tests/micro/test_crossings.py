"""Signed crossings of moves through segments: the exits of the discs and the measurement lines."""

import numpy as np

from femcrowd.micro.crossings import segment_crossings

LINE = np.array([[[0.0, 0.0], [0.0, 1.0]]])   # a -> b upwards: its right is x > 0


def test_signs_and_span():
    p0 = np.array([[-1.0, 0.5], [1.0, 0.5], [-1.0, 2.0], [-1.0, 0.5]])
    p1 = np.array([[1.0, 0.5], [-1.0, 0.5], [1.0, 2.0], [-0.5, 0.5]])
    # left to right, right to left, beside the segment, short of it
    assert segment_crossings(p0, p1, LINE)[:, 0].tolist() == [1, -1, 0, 0]


def test_a_move_ending_on_the_line():
    """PedPy counts it at its next move; an exit counts it now, and not twice."""
    p0, p1, p2 = np.array([[-1.0, 0.5]]), np.array([[0.0, 0.5]]), np.array([[1.0, 0.5]])
    assert segment_crossings(p0, p1, LINE)[0, 0] == 0 and segment_crossings(p1, p2, LINE)[0, 0] == 1
    assert segment_crossings(p0, p1, LINE, ending_counts=True)[0, 0] == 1
    assert segment_crossings(p1, p2, LINE, ending_counts=True)[0, 0] == 0


def test_many_segments_in_chunks():
    """More move-segment pairs than one chunk holds: the same as one segment at a time."""
    rng = np.random.default_rng(0)
    segments = rng.uniform(0, 1, (3000, 2, 2))
    p0, p1 = rng.uniform(0, 1, (500, 2)), rng.uniform(0, 1, (500, 2))
    whole = segment_crossings(p0, p1, segments)
    assert whole.shape == (500, 3000) and np.count_nonzero(whole) > 1000
    one = np.hstack([segment_crossings(p0, p1, segments[e : e + 1]) for e in range(0, 3000, 300)])
    assert np.array_equal(whole[:, ::300], one)
