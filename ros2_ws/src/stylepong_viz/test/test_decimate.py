"""Unit tests of the viewer's decimation, trails and batches (stylepong_viz.decimate)."""

import numpy as np
import pytest

from stylepong_viz.decimate import ColumnBuffer, Decimator, Trail


def test_decimator_keeps_the_rate_of_a_500_hz_stream():
    decimator = Decimator(100.0)
    taken = [k for k in range(5000) if decimator.due(k * 0.002)]  # 10 s at 500 Hz
    assert abs(len(taken) - 1000) <= 1
    assert set(np.diff(taken)) <= {4, 5, 6}  # stamps in floating point land either side of the grid


def test_decimator_restarts_when_time_goes_back():
    decimator = Decimator(10.0)
    assert decimator.due(100.0)
    assert not decimator.due(100.05)
    assert decimator.due(1.0)  # a restarted simulation or a new clip
    assert not decimator.due(1.05)


def test_decimator_refuses_a_rate_that_is_not_positive():
    with pytest.raises(ValueError, match='rate'):
        Decimator(0.0)


def test_trail_keeps_its_last_seconds_and_clears_on_a_restart():
    trail = Trail(seconds=1.0)
    for k in range(300):
        trail.add(k * 0.01, (k, 0.0, 0.0))
    points = trail.points()
    assert points.shape[1] == 3 and points[0, 0] in (199, 200) and points[-1, 0] == 299
    trail.add(0.0, (5.0, 5.0, 5.0))
    assert trail.points().tolist() == [[5.0, 5.0, 5.0]]


def test_column_buffer_hands_out_one_batch_and_empties():
    buffer = ColumnBuffer(3)
    buffer.add(0.0, [1, 2, 3])
    buffer.add(0.1, [4, 5, 6])
    times, values = buffer.take()
    assert times.tolist() == [0.0, 0.1] and values.shape == (2, 3)
    assert len(buffer) == 0
    with pytest.raises(ValueError, match='expected 3'):
        buffer.add(0.2, [1, 2])
