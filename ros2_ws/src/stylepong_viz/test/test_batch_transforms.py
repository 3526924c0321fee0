"""Joint rotations and link poses for a batch of joint vectors: robot_state's transforms, row by row."""

import numpy as np
import pytest

from stylepong_description import robot_model as rm
from stylepong_description.robot_state import RobotState, quaternion_from_matrix
from stylepong_viz.batch_transforms import LinkPoses, joint_rotations

STATE = RobotState(rm.urdf_xml_for_display())
JOINT_VECTORS = np.random.default_rng(7).uniform(-3.0, 3.0, (20, 6))


def _same_rotation(a_xyzw: np.ndarray, b_xyzw: np.ndarray) -> bool:
    return min(np.abs(a_xyzw - b_xyzw).max(), np.abs(a_xyzw + b_xyzw).max()) < 1e-9


def test_joint_rotations_are_robot_states():
    rotations = joint_rotations(STATE, JOINT_VECTORS)
    for row, q in enumerate(JOINT_VECTORS):
        for k, transform in enumerate(STATE.moving_transforms(q)):
            assert _same_rotation(rotations[k][row], transform.rotation_xyzw)
            # the viewer sends each rotation with its joint origin's translation, which a rotation does not move
            assert np.allclose(transform.translation_m, STATE.moving_joints[k].origin_xyz_m)


def test_a_prismatic_joint_is_refused():
    urdf = (
        '<robot name="r"><link name="a"/><link name="b"/><joint name="slide" type="prismatic">'
        '<parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>'
    )
    with pytest.raises(ValueError, match='slide'):
        joint_rotations(RobotState(urdf), np.zeros((1, 1)))


@pytest.mark.parametrize('link', [rm.TOOL_FRAME, rm.PADDLE_CENTRE_FRAME])
def test_link_poses_for_many_frames_are_robot_states(link):
    translations, rotations = LinkPoses(STATE, link).poses(JOINT_VECTORS)
    for q, translation, rotation in zip(JOINT_VECTORS, translations, rotations):
        expected_m, expected_xyzw = STATE.link_pose_in_base(link, q)
        assert np.allclose(translation, expected_m, atol=1e-12)
        assert _same_rotation(quaternion_from_matrix(rotation), expected_xyzw)
