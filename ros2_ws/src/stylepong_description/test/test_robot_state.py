"""robot_state's joint transforms (what /tf carries) against Pinocchio's forward kinematics of the same URDF."""

import pathlib
import re

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_description.robot_state import RobotState, parse_joints, quaternion_from_matrix


@pytest.mark.parametrize('seed', range(5))
def test_link_poses_match_pinocchio(seed):
    q = np.random.default_rng(seed).uniform(-3.0, 3.0, robot_model.NUM_JOINTS)
    state = RobotState(robot_model.urdf_xml_for_display())
    assert state.moving_joint_names == robot_model.JOINT_NAMES
    model = robot_model.pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    for frame in ('wrist_2_link', robot_model.TOOL_FRAME, robot_model.PADDLE_CENTRE_FRAME):
        translation, rotation = state.link_pose_in_base(frame, q)
        placement = data.oMf[model.getFrameId(frame)]
        assert np.allclose(translation, placement.translation, atol=1e-12)
        expected = quaternion_from_matrix(placement.rotation)
        assert min(np.abs(rotation - expected).max(), np.abs(rotation + expected).max()) < 1e-12


def test_fixed_and_moving_transforms_cover_every_joint():
    state = RobotState(robot_model.urdf_xml())
    moving = state.moving_transforms(np.zeros(robot_model.NUM_JOINTS))
    assert [t.child for t in moving] == [
        'shoulder_link',
        'upper_arm_link',
        'forearm_link',
        'wrist_1_link',
        'wrist_2_link',
        'wrist_3_link',
    ]
    assert {t.child for t in state.fixed_transforms()} >= {
        robot_model.TOOL_FRAME,
        robot_model.PADDLE_BODY,
        robot_model.PADDLE_CENTRE_FRAME,
    }
    named = state.moving_transforms_by_name(['elbow_joint', 'not_a_joint'], [0.5, 1.0])
    assert [t.child for t in named] == ['forearm_link']


def test_display_urdf_points_at_mesh_files_that_exist():
    xml = robot_model.urdf_xml_for_display()
    assert robot_model.MESH_PACKAGE_URI not in xml
    paths = re.findall(r'filename="file://([^"]+)"', xml)
    assert paths and all(pathlib.Path(p).is_file() for p in paths)


def test_a_joint_without_a_child_is_refused():
    with pytest.raises(ValueError, match="'broken'"):
        parse_joints('<robot><joint name="broken" type="fixed"><parent link="a"/></joint></robot>')
