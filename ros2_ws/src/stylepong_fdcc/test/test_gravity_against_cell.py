"""Tool gravity compensation checked against the MuJoCo cell's wrist sensor, not against itself.

drag_teach removes the paddle's weight with `gravity_wrench_on_tool`, computed from the robot model's
paddle mass and centre of mass (Pinocchio). The reference here is independent of that code: the cell's
MuJoCo force/torque sensor between wrist_3 and the tool (`Cell.tool_wrench(include_inertia=True)`, the
physical sensor's reading) with the arm held still at several poses, with and without a hand pushing.
"""

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_fdcc.fdcc_config import FdccConfig
from stylepong_fdcc.wrench_conditioning import WrenchConditioner, gravity_wrench_on_tool, tool_load_from_model
from stylepong_sim import world_spec
from stylepong_sim.cells.cell import Cell

MODEL = robot_model.pinocchio_model()
DATA = MODEL.createData()
GRAVITY = np.array(MODEL.gravity.linear)
HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
# Poses that turn the tool through very different orientations (wrist up, sideways, tilted, rolled).
POSES = {
    'home': HOME,
    'wrist_tilted': HOME + np.array([0.3, 0.2, -0.4, 0.8, 0.5, 1.0]),
    'wrist_rolled': HOME + np.array([-0.4, -0.2, 0.3, -1.0, 1.2, -2.0]),
    'tool_sideways': HOME + np.array([0.0, 0.0, 0.0, 0.0, 1.5708, 0.7]),
    'elbow_up': HOME + np.array([0.2, -0.4, 0.6, -0.6, -0.8, 2.5]),
}
# The model's gravity and the cell's agree, so a mismatch below is the compensation's, not the world's.
assert np.allclose(GRAVITY, [0.0, 0.0, -world_spec.GRAVITY_M_S2])
# Agreement at rest: the sensor also carries the residual accelerations of an arm held by its servo.
FORCE_TOLERANCE_N = 0.01
TORQUE_TOLERANCE_NM = 0.002


def held_still(q, hand_force_world=None, settle_s: float = 1.0) -> Cell:
    cell = Cell(home_joint_positions_rad=q)
    if hand_force_world is not None:
        cell.set_hand_wrench(hand_force_world, frame='world')
    cell.step_for(settle_s)
    assert np.abs(cell.joint_velocities_rad_s).max() < 1e-3, 'the arm is not at rest'
    return cell


def tool_rotation_base(q) -> np.ndarray:
    pin.framesForwardKinematics(MODEL, DATA, q)
    return DATA.oMf[MODEL.getFrameId(robot_model.TOOL_FRAME)].rotation.copy()


def sensor_reading(cell: Cell) -> np.ndarray:
    force, torque = cell.tool_wrench(include_inertia=True)
    return np.concatenate([force, torque])


@pytest.mark.parametrize('name', list(POSES))
def test_the_compensated_weight_is_what_the_cells_sensor_reads_at_rest(name):
    cell = held_still(POSES[name])
    measured = sensor_reading(cell)
    # The cell's base_link is not rotated in the world (ROBOT_BASE_YAW_RAD = 0), so base axes = world axes.
    predicted = gravity_wrench_on_tool(
        tool_load_from_model(MODEL), tool_rotation_base(cell.joint_positions_rad), GRAVITY
    )
    # The paddle weighs a few newtons; a wrong rotation or lever shows up far above the tolerance.
    assert np.linalg.norm(measured[:3]) > 1.0
    np.testing.assert_allclose(predicted[:3], measured[:3], atol=FORCE_TOLERANCE_N)
    np.testing.assert_allclose(predicted[3:], measured[3:], atol=TORQUE_TOLERANCE_NM)


@pytest.mark.parametrize('name', ['home', 'wrist_rolled', 'tool_sideways'])
def test_drag_teachs_conditioner_turns_the_cells_sensor_into_the_hand_force(name):
    """The whole path drag_teach uses: the sensor reading in, gravity out, the hand's force in base axes."""
    hand = np.array([4.0, -3.0, 2.0])
    cell = held_still(POSES[name], hand_force_world=hand)
    conditioner = WrenchConditioner(
        FdccConfig(force_deadband_n=0.0, torque_deadband_nm=0.0), tool_load_from_model(MODEL), GRAVITY
    )
    rotation = tool_rotation_base(cell.joint_positions_rad)
    for k in range(50):
        cell.step()
        conditioner.add_sample(sensor_reading(cell), rotation, k * cell.dt_s)
    out = conditioner.output()
    # The hand acts at tool0's origin: a pure force, no torque about that point.
    np.testing.assert_allclose(out[:3], hand, atol=FORCE_TOLERANCE_N)
    np.testing.assert_allclose(out[3:], 0.0, atol=TORQUE_TOLERANCE_NM)
