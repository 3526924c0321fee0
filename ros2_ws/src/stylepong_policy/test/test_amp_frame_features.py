"""amp_frame_features (stylepong_policy.experiments): its windows stay inside one episode and its two measures
are right (no actor, no training)."""

import pytest
import torch

from stylepong_policy.experiments import amp_frame_features as tool


def test_windows_never_cross_an_episode_end():
    """One environment whose frames count the steps; its episode ends at steps 3 and 7. The frames after
    steps 3 and 7 are still the ended episodes' own; frames 4 and 8 begin the next ones."""
    frames = torch.arange(11, dtype=torch.float32).reshape(11, 1, 1)
    ended = torch.zeros(10, 1, dtype=torch.bool)
    ended[[2, 6]] = True  # steps 3 and 7
    windows = tool.episode_windows(frames, ended, 3).squeeze(-1).tolist()
    assert sorted(windows) == [[0, 1, 2], [1, 2, 3], [4, 5, 6], [5, 6, 7], [8, 9, 10]]


def test_nearest_demonstration_distance_uses_positions_only():
    """Windows of one joint (q, qdot): the velocity column must not count, the distance is the root mean
    square over the frames of the nearest reference window."""
    reference = torch.tensor([[[0.0, 9.0], [0.0, 9.0]], [[1.0, -9.0], [1.0, -9.0]]])
    windows = torch.tensor([[[0.1, 0.0], [0.3, 0.0]], [[1.0, 5.0], [1.0, 5.0]]])
    distance = tool.nearest_demonstration_rad(windows, reference)
    assert distance.tolist() == pytest.approx([(0.1**2 + 0.3**2) ** 0.5 / 2**0.5, 0.0])


def test_rank_correlation_is_one_for_the_same_order_and_minus_one_reversed():
    x = torch.tensor([0.3, -1.0, 2.0, 0.5])
    assert tool.rank_correlation(x, x**3) == pytest.approx(1.0)
    assert tool.rank_correlation(x, -x) == pytest.approx(-1.0)
