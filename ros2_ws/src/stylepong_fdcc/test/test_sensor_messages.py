"""Joint states and wrenches read from their bytes give exactly what rclpy's deserialiser gives."""

import math

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from stylepong_description import robot_model
from stylepong_fdcc.sensor_messages import JointStateReader, wrench_from_cdr

NAMES = list(robot_model.JOINT_NAMES)


def joint_state(names, positions, frame_id='', velocities=None) -> bytes:
    msg = JointState()
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
    msg.name = names
    msg.position = positions
    msg.velocity = velocities if velocities is not None else [0.5] * len(positions)
    return serialize_message(msg)


@pytest.mark.parametrize('frame_id', ['', 'b', 'base_link', 'xyz'])
@pytest.mark.parametrize('order', [NAMES, NAMES[::-1], ['gripper'] + NAMES[2:] + NAMES[:2]])
def test_positions_come_back_in_urdf_order_bit_for_bit(frame_id, order):
    rng = np.random.default_rng(len(frame_id) + len(order))
    values = {n: float(v) for n, v in zip(order, rng.normal(0.0, 2.0, len(order)))}
    values[order[-1]] = math.nan
    reader = JointStateReader(robot_model.JOINT_NAMES)
    for _ in range(2):  # the second time from the remembered name block
        positions, names, count = reader.positions(joint_state(order, [values[n] for n in order], frame_id))
        expected = np.array([values[n] for n in NAMES])
        assert names == count == len(order)
        assert positions.dtype == np.float64 and np.array_equal(positions, expected, equal_nan=True)


def test_a_missing_joint_or_a_short_position_list_gives_none_even_after_good_messages():
    reader = JointStateReader(robot_model.JOINT_NAMES)
    assert reader.positions(joint_state(NAMES, [0.1] * 6))[0] is not None
    assert reader.positions(joint_state(NAMES[1:], [0.1] * 5))[0] is None
    assert reader.positions(joint_state(NAMES, [0.1] * 5)) == (None, 6, 5)
    assert reader.positions(joint_state(NAMES, [0.2] * 6))[0].tolist() == [0.2] * 6


def test_a_buffer_that_breaks_the_layout_is_read_by_rclpy_instead(monkeypatch):
    import stylepong_fdcc.sensor_messages as sensor_messages

    handed_over = []

    def deserialize(raw, msg_type):
        handed_over.append(msg_type)
        msg = JointState()
        msg.name, msg.position = NAMES, [0.7] * 6
        return msg

    monkeypatch.setattr(sensor_messages, 'deserialize_message', deserialize)
    raw = joint_state(NAMES, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    reader = JointStateReader(robot_model.JOINT_NAMES)
    assert reader.positions(bytes([0x00, 0x00]) + raw[2:])[0].tolist() == [0.7] * 6  # says big endian
    assert reader.positions(raw[:40])[0].tolist() == [0.7] * 6  # truncated
    assert handed_over == [JointState, JointState]
    assert reader.positions(raw)[0].tolist() == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6] and len(handed_over) == 2


@pytest.mark.parametrize('frame_id', ['', 't', 'tool0', 'tool0_x'])
def test_wrench_comes_back_bit_for_bit(frame_id):
    msg = WrenchStamped()
    msg.header.frame_id = frame_id
    values = [1.5, -2.25, math.inf, -1e300, math.nan, 5e-324]
    (
        msg.wrench.force.x,
        msg.wrench.force.y,
        msg.wrench.force.z,
        msg.wrench.torque.x,
        msg.wrench.torque.y,
        msg.wrench.torque.z,
    ) = values
    wrench = wrench_from_cdr(serialize_message(msg))
    assert wrench.dtype == np.float64 and wrench.flags.writeable
    assert np.array_equal(wrench, np.array(values), equal_nan=True)
