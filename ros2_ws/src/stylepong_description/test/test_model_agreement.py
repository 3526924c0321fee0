"""Pinocchio and MuJoCo load the one UR5 + paddle description and agree on it."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model

N_CONFIGURATIONS = 50


@pytest.fixture(scope='module')
def models():
    model = robot_model.pinocchio_model()
    mj_model = robot_model.mujoco_model()
    return model, model.createData(), mj_model, mujoco.MjData(mj_model)


def _random_configurations(n: int) -> np.ndarray:
    limits = robot_model.joint_limits()
    rng = np.random.default_rng(1234)
    return rng.uniform(np.maximum(limits.lower_rad, -np.pi), np.minimum(limits.upper_rad, np.pi), size=(n, 6))


def test_joint_order_is_the_urdf_order(models):
    model, _, mj_model, _ = models
    assert tuple(model.names[1:]) == robot_model.JOINT_NAMES
    assert tuple(mj_model.joint(i).name for i in range(mj_model.njnt)) == robot_model.JOINT_NAMES
    # One generalised coordinate per joint, in the same order, in both.
    assert [mj_model.jnt_qposadr[i] for i in range(6)] == list(range(6))


def test_paddle_mass_and_frames(models):
    model, _, mj_model, _ = models
    assert model.existFrame(robot_model.PADDLE_CENTRE_FRAME) and model.existFrame(robot_model.TOOL_FRAME)
    paddle_mass = (
        model.inertias[model.frames[model.getFrameId(robot_model.PADDLE_BODY)].parentJoint].mass
        - _upstream_wrist_3_mass()
    )
    assert paddle_mass == pytest.approx(0.17, abs=1e-9)
    assert mj_model.body(robot_model.PADDLE_BODY).mass[0] == pytest.approx(0.17, abs=1e-12)


def _upstream_wrist_3_mass() -> float:
    return 0.1879  # example-robot-data ur5_robot.urdf, link wrist_3_link


def test_paddle_centre_pose_agrees(models):
    model, data, mj_model, mj_data = models
    frame = model.getFrameId(robot_model.PADDLE_CENTRE_FRAME)
    body = mj_model.body(robot_model.PADDLE_CENTRE_FRAME).id
    for q in _random_configurations(N_CONFIGURATIONS):
        pin.framesForwardKinematics(model, data, q)
        mj_data.qpos[:] = q
        mujoco.mj_kinematics(mj_model, mj_data)
        pose = data.oMf[frame]
        np.testing.assert_allclose(mj_data.xpos[body], pose.translation, atol=1e-6, rtol=0)
        np.testing.assert_allclose(mj_data.xmat[body].reshape(3, 3), pose.rotation, atol=1e-6, rtol=0)


def test_paddle_centre_geometry():
    """The blade centre lies 0.175 m along tool0 z and its z axis is the face normal (tool0 x)."""
    model = robot_model.pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.zeros(6))
    tool = data.oMf[model.getFrameId(robot_model.TOOL_FRAME)]
    centre = data.oMf[model.getFrameId(robot_model.PADDLE_CENTRE_FRAME)]
    relative = tool.actInv(centre)
    np.testing.assert_allclose(relative.translation, [0, 0, robot_model.PADDLE.centre_offset_m], atol=1e-12)
    np.testing.assert_allclose(relative.rotation[:, 2], [1, 0, 0], atol=1e-12)


def test_mass_matrix_agrees(models):
    model, data, mj_model, mj_data = models
    dense = np.zeros((mj_model.nv, mj_model.nv))
    for q in _random_configurations(N_CONFIGURATIONS):
        mass_pin = pin.crba(model, data, q)
        mass_pin = np.triu(mass_pin) + np.triu(mass_pin, 1).T
        mj_data.qpos[:] = q
        mujoco.mj_forward(mj_model, mj_data)
        mujoco.mj_fullM(mj_model, mj_data, dense)  # MuJoCo 4 signature
        relative = np.linalg.norm(dense - mass_pin) / np.linalg.norm(mass_pin)
        assert relative < 1e-6, relative
