"""The recorder node's small decisions: where a relative output_dir goes, which QoS it subscribes with,
how offered QoS is stored."""

from pathlib import Path

from rclpy.duration import Infinite
from rclpy.qos import QoSPresetProfiles, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import QosDurability, QosReliability, QosTime

from stylepong_recording.recorder_node import resolve_output_dir, rosbags_qos, subscription_reliability


def test_a_relative_output_dir_is_taken_from_the_project_root_not_the_current_directory():
    cwd = Path('/srv/someone/somewhere')
    isolated = Path('/srv/project/ros2_ws/install/stylepong_recording')
    merged = Path('/srv/project/ros2_ws/install')
    assert resolve_output_dir('ros2_ws/bags', isolated, cwd) == Path('/srv/project/ros2_ws/bags')
    assert resolve_output_dir('ros2_ws/bags', merged, cwd) == Path('/srv/project/ros2_ws/bags')
    assert resolve_output_dir('ros2_ws/bags', Path('/opt/ros/jazzy'), cwd) == cwd / 'ros2_ws/bags'
    assert resolve_output_dir('ros2_ws/bags', None, cwd) == cwd / 'ros2_ws/bags'
    assert resolve_output_dir('/data/clips', isolated, cwd) == Path('/data/clips')
    assert resolve_output_dir('~/clips', isolated, cwd) == Path.home() / 'clips'


def test_reliable_unless_a_publisher_only_offers_best_effort():
    assert subscription_reliability([]) == ReliabilityPolicy.RELIABLE
    assert subscription_reliability([ReliabilityPolicy.RELIABLE]) == ReliabilityPolicy.RELIABLE
    assert (
        subscription_reliability([ReliabilityPolicy.RELIABLE, ReliabilityPolicy.BEST_EFFORT])
        == ReliabilityPolicy.BEST_EFFORT
    )


def test_offered_qos_is_stored_as_rosbag2_writes_it():
    sensor = rosbags_qos(QoSPresetProfiles.SENSOR_DATA.value)
    assert sensor.reliability == QosReliability.BEST_EFFORT
    assert sensor.durability == QosDurability.VOLATILE
    assert sensor.depth == 5
    assert sensor.deadline == QosTime(0, 0)
    # The graph reports rmw's "infinite" duration; rosbag2 stores it as sec 9223372036, nsec 854775807.
    profile = QoSProfile(depth=10, deadline=Infinite)
    assert rosbags_qos(profile).deadline == QosTime(9223372036, 854775807)
