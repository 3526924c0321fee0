"""Replaying a joint-position sequence against incoming balls (stylepong_policy.evaluation.demo_replay)."""

import pathlib

import numpy as np
import pytest
import torch

from stylepong_policy.evaluation import demo_replay
from stylepong_policy.training.dataset import ReferenceDataset
from stylepong_sim import world_spec

ALL_SPEEDS = tuple(world_spec.SPEED_RANGES_M_S['all'])
HIT_STEPS = list(range(20, 66))
WRIST_1 = 3


def test_the_fastest_frame_and_the_targets_around_it():
    q = np.zeros((10, 6))
    q[6:, 0] = 0.5  # the largest jump is into frame 6
    assert demo_replay.fastest_frame(q, 60.0) == 6
    hit_steps = torch.tensor([20, 30])
    # The fastest frame falls at each env's hit step; the first frame holds before, the last after.
    assert demo_replay.clip_targets(q, 20, hit_steps, 6)[0].tolist() == [0.5, 0.0]
    assert demo_replay.clip_targets(q, 0, hit_steps, 6)[0].tolist() == [0.0, 0.0]
    assert demo_replay.clip_targets(q, 99, hit_steps, 6)[0].tolist() == [0.5, 0.5]
    with pytest.raises(ValueError):
        demo_replay.replay_clip(np.zeros((5, 3)), 4, HIT_STEPS, 900, ALL_SPEEDS)


def test_an_arm_held_at_home_returns_nothing():
    home = np.tile(np.array(world_spec.HOME_JOINT_POSITIONS_RAD), (5, 1))
    outcome = demo_replay.replay_clip(home, 20, [30, 40], 900, ALL_SPEEDS)
    assert outcome.balls == 20 and outcome.returned == 0 and outcome.hit <= 20
    assert sum(outcome.hit_verdicts.values()) >= outcome.hit


def test_the_shipped_opened_blade_returns_the_ball_and_an_upright_one_seldom_does(tmp_path):
    """The shipped forward clip at x5 (the nearest to the policies' strokes) against 60 balls, as recorded
    (the teacher opened the blade 0.6 rad: teacher.TeacherConfig.blade_pitch_rad) and with the blade turned
    upright again by turning wrist_1 back by 0.6 rad."""
    bags = pathlib.Path(__file__).resolve().parents[3] / 'bags'
    if not any(bags.glob('*/metadata.yaml')):
        pytest.skip('no shipped clips in ros2_ws/bags')
    from stylepong_policy.training import build_dataset

    assert build_dataset.run([str(bags), '-o', str(tmp_path / 'dataset.npz')]) == 0
    dataset = ReferenceDataset.load(tmp_path / 'dataset.npz')
    clip = dataset.clip(int(dataset.select(labels=['forward'], speed_factors=[5])[0])).q
    opened = demo_replay.replay_clip(clip, 60, HIT_STEPS, 900, ALL_SPEEDS)
    upright_q = clip.copy()
    upright_q[:, WRIST_1] += 0.6
    upright = demo_replay.replay_clip(upright_q, 60, HIT_STEPS, 900, ALL_SPEEDS)
    # Of the (ball, start) pairs that hit, the opened blade returns a third (34 of 99 here), the upright
    # one a twentieth (3 of 55): it strikes the ball down onto the robot's own half or out.
    assert opened.returned >= 5 and returned_share(opened) > 0.25
    assert upright.hit >= 5 and returned_share(upright) < 0.1


def returned_share(outcome: demo_replay.ReplayOutcome) -> float:
    return outcome.hit_verdicts.get('returned', 0) / sum(outcome.hit_verdicts.values())
