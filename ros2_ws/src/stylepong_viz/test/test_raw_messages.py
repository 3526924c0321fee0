"""Stamps and joint states read from serialized messages as rclpy writes them."""

import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from stylepong_msgs.msg import BallState
from stylepong_recording.joint_state_cdr import CdrLayoutError
from stylepong_viz.raw_messages import JointStateBytes, header_stamp_s


def _joint_state(frame_id: str = '') -> JointState:
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345_000_000
    msg.header.frame_id = frame_id
    msg.name = ['a', 'bb', 'ccc']
    msg.position, msg.velocity = [0.5, -1.25, 3.0], [0.1, 0.2, 0.3]
    return msg


@pytest.mark.parametrize('frame_id', ['', 'base_link', 'x' * 13])
def test_a_joint_state_is_read_from_its_bytes(frame_id):
    raw = serialize_message(_joint_state(frame_id))
    assert header_stamp_s(raw) == pytest.approx(12.345)
    names, positions, velocities = JointStateBytes().read(raw)
    assert names == ('a', 'bb', 'ccc') and positions == (0.5, -1.25, 3.0) and velocities == (0.1, 0.2, 0.3)


def test_the_stamp_of_any_header_first_message():
    msg = BallState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 500_000_000
    assert header_stamp_s(serialize_message(msg)) == pytest.approx(3.5)


def test_bytes_that_are_not_little_endian_cdr_have_no_stamp_and_no_layout():
    raw = serialize_message(_joint_state())
    assert header_stamp_s(b'\x00\x00' + raw[2:]) is None and header_stamp_s(raw[:10]) is None
    with pytest.raises(CdrLayoutError):
        JointStateBytes().read(raw[:40])
