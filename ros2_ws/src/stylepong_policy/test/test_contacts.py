"""stylepong_policy.evaluation.contacts: the blade at a contact, for known poses, strokes and demonstrations."""

import numpy as np
import pytest
from synthetic_reference import write_reference  # beside this file: conftest.py

from stylepong_policy.evaluation import contacts
from stylepong_policy.evaluation.strokes import Stroke, paddle_home_position_m
from stylepong_policy.training.dataset import ReferenceDataset, hit_frame
from stylepong_sim import world_spec

HOME = np.asarray(world_spec.HOME_JOINT_POSITIONS_RAD, dtype=float)
WRIST_3 = 5


def test_the_home_pose_meets_the_ball_square_upright_and_at_home():
    (blade,) = contacts.blades(HOME[None], np.zeros((1, 6)))
    assert blade.ahead_m == pytest.approx(0.0, abs=1e-9)
    assert blade.opening_deg == pytest.approx(0.0, abs=0.1) and blade.facing_deg == pytest.approx(0.0, abs=0.1)
    assert blade.speed_m_s == 0.0


def test_the_blade_speed_is_the_paddle_centre_s_turning_about_the_base_for_the_shoulder_pan():
    paddle = np.asarray(paddle_home_position_m())
    base = np.asarray(world_spec.ROBOT_BASE_POSITION_M)
    radius_m = float(np.hypot(*(paddle - base)[:2]))  # the pan axis is the base's vertical axis
    pan = np.zeros((1, 6))
    pan[0, 0] = 2.0
    (blade,) = contacts.blades(HOME[None], pan)
    assert blade.speed_m_s == pytest.approx(2.0 * radius_m, rel=1e-3)
    with pytest.raises(ValueError, match='joint velocities'):
        contacts.blades(HOME[None], np.zeros((2, 6)))
    # A stroke holds positions: its speed is over the frame that ends at the contact (60 Hz).
    swung = _stroke('forward', True, HOME)
    swung.joint_positions_rad[3, 0] -= 2.0 / 60.0
    (found,) = contacts.actor_contacts([swung])['forward']
    assert found.speed_m_s == pytest.approx(2.0 * radius_m, rel=1e-3)


def test_turning_the_last_wrist_joint_turns_the_face_one_way_and_then_the_other():
    turned = np.repeat(HOME[None], 2, axis=0)
    turned[:, WRIST_3] += [0.3, -0.3]
    left, right = contacts.blades(turned, np.zeros((2, 6)))
    # The face normal leaves the vertical plane through the table's axis, or tips up or down: some angle
    # moves by about the turn, in opposite directions for opposite turns.
    moved = np.array([[left.opening_deg, left.facing_deg], [right.opening_deg, right.facing_deg]])
    assert np.abs(moved).max() == pytest.approx(np.degrees(0.3), abs=1.0)
    assert np.allclose(moved[0], -moved[1], atol=0.5)
    assert contacts.blades(np.zeros((0, 6)), np.zeros((0, 6))) == []


def _stroke(direction: str, hit: bool, q_at_hit: np.ndarray) -> Stroke:
    q = np.repeat(HOME[None], 10, axis=0)
    q[3:5] = q_at_hit  # at rest at the contact
    return Stroke(
        seed=0,
        ball=0,
        joint_positions_rad=q,
        ball_position_m=np.zeros((10, 3)),
        direction=direction,
        arrival_y_m=0.0,
        launch_velocity_m_s=np.zeros(3),
        outcome='returned' if hit else 'no_hit',
        success=hit,
        hit=hit,
        hit_frame=4 if hit else -1,
        verdict_frame=9,
    )


def test_an_actor_s_contact_is_its_pose_at_the_hit_frame_and_a_miss_has_none():
    turned = HOME.copy()
    turned[WRIST_3] += 0.3
    found = contacts.actor_contacts(
        [_stroke('leftward', True, turned), _stroke('leftward', False, HOME), _stroke('forward', True, HOME)]
    )
    assert [len(found[d]) for d in ('leftward', 'forward')] == [1, 1] and 'rightward' not in found
    assert found['leftward'][0] == contacts.blades(turned[None], np.zeros((1, 6)))[0]
    means = contacts.mean_blades(found)
    assert means['rightward'] is None and means['forward']['contacts'] == 1
    header, rows = contacts.contact_table({'actor': means})
    assert len(header) == 7 and [row[1] for row in rows] == ['forward', 'leftward']


def test_a_demonstration_s_contact_is_each_original_clip_s_hit(tmp_path):
    dataset = ReferenceDataset.load(write_reference(tmp_path / 'clips.npz'))
    found = contacts.demonstrated_contacts(dataset)
    originals = dataset.select(speed_factors=[1])
    assert sum(len(v) for v in found.values()) == len(originals)
    first = int(originals[0])
    frame = int(dataset.clip_start[first]) + hit_frame(dataset.clip(first).qd)
    fastest = dataset.speed_factor.max()
    assert fastest > 1
    expected = contacts.blades(dataset.q[frame][None], fastest * dataset.qd[frame][None])[0]
    assert found[str(dataset.label[first])][0] == expected
