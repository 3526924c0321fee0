"""The pose prior (rl.pose_prior) and how the motion prior uses it: the reward of a pose against its label's
demonstrated pose at the same time from the hit, labels without clips, and the mixed reward."""

import math

import numpy as np
import pytest
import torch
from synthetic_reference import write_reference  # beside this file: conftest.py

from stylepong_description.robot_cell import STROKE_LABELS as LABELS
from stylepong_policy.rl.amp import MotionPrior, ReferenceMotion
from stylepong_policy.rl.config import AMPConfig
from stylepong_policy.rl.pose_prior import PosePrior
from stylepong_policy.training.dataset import ReferenceDataset


def line_clip(frames: int, hit: int, joint: int = 0) -> tuple[np.ndarray, int]:
    """A clip whose joint `joint` reads its frame index (rad), with its hit frame."""
    q = np.zeros((frames, 6))
    q[:, joint] = np.arange(frames)
    return q, hit


def test_reference_is_the_clip_frame_at_the_same_time_from_the_hit():
    prior = PosePrior([[line_clip(10, 4)]], sigma_rad=0.5, rate_hz=10.0)
    q = torch.zeros(5, 6)
    time_s = torch.tensor([0.0, -0.2, 0.3, -5.0, 5.0])  # frames 4, 2, 7, before the start, after the end
    expected = [4.0, 2.0, 7.0, 0.0, 9.0]
    assert prior.reference_distance_rad(q, time_s).tolist() == pytest.approx(expected)
    q[:, 0] = torch.tensor(expected)
    assert prior.reward(q, time_s).tolist() == pytest.approx([1.0] * 5)
    q[0, 0] = 5.0
    assert prior.reward(q, time_s)[0].item() == pytest.approx(math.exp(-1.0 / 0.5))


def test_after_the_touch_the_follow_through_ends_with_the_stroke():
    """follow_through_s: the clip's frames after its hit are spread over the stroke's time after the touch,
    so the stroke's last frame is paired with the clip's last, as DTW pairs them; before it, no change."""
    prior = PosePrior(
        [[line_clip(10, 4), line_clip(24, 4, joint=1)]], sigma_rad=0.5, rate_hz=10.0, follow_through_s=0.5
    )
    time_s = torch.tensor([-0.2, 0.0, 0.25, 0.5, 3.0])
    frames = prior._reference_frames(prior.labels[0], time_s)
    assert frames[:, 0].tolist() == [2, 4, 6, 9, 9]  # 5 frames after the hit in 0.5 s
    assert frames[:, 1].tolist() == [2, 4, 14, 23, 23]  # 19 frames after the hit in the same 0.5 s
    on_own_clock = PosePrior([[line_clip(10, 4), line_clip(24, 4, joint=1)]], sigma_rad=0.5, rate_hz=10.0)
    assert on_own_clock._reference_frames(on_own_clock.labels[0], time_s)[:, 1].tolist() == [2, 4, 6, 9, 23]
    q = torch.zeros(1, 6)
    q[0, 1] = 23.0  # the long clip's end at the stroke's end
    assert prior.reward(q, torch.tensor([0.5])).item() == pytest.approx(1.0)
    assert on_own_clock.reward(q, torch.tensor([0.5])).item() < 1e-6
    with pytest.raises(ValueError, match='follow-through'):
        PosePrior([[line_clip(4, 1)]], sigma_rad=0.3, rate_hz=60.0, follow_through_s=0.0)


def test_the_nearest_clip_of_the_label_counts_and_other_labels_do_not():
    prior = PosePrior(
        [[line_clip(10, 4, joint=0), line_clip(10, 4, joint=1)], [line_clip(5, 2, joint=2)]],
        sigma_rad=1.0,
        rate_hz=10.0,
    )
    q = torch.zeros(2, 6)
    q[:, 1] = 4.0  # on the second clip of label 0 at the hit, 4 rad off label 1's clip
    distance = prior.reference_distance_rad(q, torch.zeros(2), torch.tensor([0, 1]))
    assert distance[0].item() == pytest.approx(0.0)
    assert distance[1].item() == pytest.approx(math.hypot(4.0, 2.0))


def test_a_label_without_clips_earns_nothing():
    prior = PosePrior([[line_clip(4, 1)], []], sigma_rad=0.3, rate_hz=60.0)
    reward = prior.reward(torch.zeros(3, 6), torch.zeros(3), torch.tensor([0, 1, 1]))
    assert reward[1:].tolist() == [0.0, 0.0] and prior.labels_with_clips.tolist() == [True, False]


def test_bad_priors_are_refused():
    with pytest.raises(ValueError, match='sigma'):
        PosePrior([[line_clip(4, 1)]], sigma_rad=0.0, rate_hz=60.0)
    with pytest.raises(ValueError, match='no demonstrated clip'):
        PosePrior([[], []], sigma_rad=0.3, rate_hz=60.0)
    with pytest.raises(ValueError, match='hit frame'):
        PosePrior([[line_clip(4, 7)]], sigma_rad=0.3, rate_hz=60.0)


@pytest.fixture(scope='module')
def forward_only(tmp_path_factory):
    """A dataset of forward clips only (originals and speed-ups)."""
    path = write_reference(tmp_path_factory.mktemp('pose') / 'forward.npz', labels=('forward', 'forward'))
    return ReferenceDataset.load(path)


def test_from_dataset_takes_every_clip_of_each_label(forward_only):
    prior = PosePrior.from_dataset(forward_only, LABELS, sigma_rad=0.3)
    assert [clips.count for clips in prior.labels] == [forward_only.num_clips, 0, 0]
    # A demonstrated clip played on the clock of its own hit is at distance 0 all along.
    clip = forward_only.clip(0)
    hit = int(prior.labels[0].hit_frames[0])
    time_s = (torch.arange(len(clip.q)) - hit) / forward_only.rate_hz
    q = torch.as_tensor(clip.q, dtype=torch.float32)
    assert prior.reference_distance_rad(q, time_s, torch.zeros(len(q), dtype=torch.long)).max() < 1e-5


def test_motion_prior_gives_no_style_to_a_label_without_clips_and_mixes_the_pose(forward_only):
    cfg = AMPConfig(
        sequence_length=2, frame_features='q', condition_on_label=True, w_style=0.5, w_pose=2.0, pose_sigma_rad=0.3
    )
    reference = ReferenceMotion.from_dataset(forward_only, 2, features='q', label_names=LABELS)
    prior = MotionPrior(
        cfg, reference, 12, num_envs=3, device='cpu', pose_prior=PosePrior.from_dataset(forward_only, LABELS, 0.3)
    )
    frames = torch.as_tensor(forward_only.states()[:3], dtype=torch.float32)
    prior.start(frames)
    labels = torch.tensor([0, 1, 2])
    style = prior.observe(frames, torch.zeros(3, dtype=torch.bool), frames, labels)
    assert style[1:].tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match='style_time_s'):
        prior.pose_reward(frames, None, labels)
    pose = prior.pose_reward(frames, torch.zeros(3), labels)
    assert pose[0].item() > 0.0 and pose[1:].tolist() == [0.0, 0.0]
    task = torch.tensor([1.0, 2.0, 3.0])
    mixed = prior.mix(task, style, pose=pose)
    assert mixed.tolist() == pytest.approx((task + 0.5 * style + 2.0 * pose).tolist())


def test_stroke_prior_rewards_each_stroke_once_by_its_dtw_to_the_nearest_clip_of_its_label():
    from stylepong_policy.evaluation.style_metrics import dtw_distance_rad
    from stylepong_policy.rl.stroke_prior import StrokePrior

    clip = line_clip(4, 1)[0]
    prior = StrokePrior([[clip], []], sigma_rad=0.5, num_envs=3, joints=6)
    frames = torch.zeros(3, 6)
    prior.start(frames)
    no = torch.zeros(3, dtype=torch.bool)
    labels = torch.tensor([0, 0, 1])
    rewards = []
    for step in range(1, 4):
        frames = torch.zeros(3, 6)
        frames[:, 0] = float(step)
        end = torch.tensor([step == 3, False, step == 3])
        rewards.append(prior.observe(frames, end, no, frames, labels))
    assert all(r.abs().sum() == 0 for r in rewards[:2])
    stroke = np.zeros((4, 6))
    stroke[:, 0] = np.arange(4)
    assert rewards[2][0].item() == pytest.approx(math.exp(-dtw_distance_rad(stroke, clip) / (0.5 * 4)))
    assert rewards[2][0].item() == pytest.approx(1.0)  # the clip itself
    assert rewards[2][1:].tolist() == [0.0, 0.0]  # still going; a label without clips
    # An ended stroke earns nothing more until its episode ends; the episode's end ends the other stroke.
    done = torch.tensor([True, True, False])
    after = prior.observe(torch.full((3, 6), 9.0), no, done, torch.zeros(3, 6), labels)
    assert after[0].item() == 0.0 and 0.0 < after[1].item() < 1.0
    assert prior.lengths.tolist() == [1, 1, 4]
