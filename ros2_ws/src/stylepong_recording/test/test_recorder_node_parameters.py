"""The recorder's parameters: the YAML file and the node's table agree; bad ones are refused in one line
naming them, with stylepong_common's exit code, by the command and by its old stylepong_fdcc name."""

import pathlib

import pytest
import rclpy
import yaml
from rclpy.parameter import Parameter

from stylepong_common.node_support import ParameterError
from stylepong_recording.recorder_node import PARAMETERS, RecorderNode

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'recorder.yaml'
# The YAML file leaves `topics` out: rcl cannot parse the empty list that is its default.
NOT_IN_YAML = {'topics'}


def test_the_yaml_file_holds_every_parameter_with_the_node_default():
    values = yaml.safe_load(CONFIG.read_text())['recorder']['ros__parameters']
    rows = [row for row in PARAMETERS if row.name not in NOT_IN_YAML]
    assert list(values) == [row.name for row in rows]
    for row in rows:
        assert values[row.name] == row.default and type(values[row.name]) is type(row.default), row.name


def test_integers_pass_for_floats_and_extra_topics_are_resolved(tmp_path):
    rclpy.init()
    try:
        node = RecorderNode(
            parameter_overrides=[
                Parameter('output_dir', value=str(tmp_path)),
                Parameter('min_free_space_mb', value=5),
                Parameter('topics', value=['/ball/state', 'joint_states']),
            ]
        )
        assert node.output_dir == tmp_path and node.min_free_space_mb == 5.0
        assert node.topics == ['/joint_states', '/ball/state']
        node.destroy_node()
    finally:
        rclpy.try_shutdown()


@pytest.mark.parametrize(
    'override',
    [
        Parameter('flush_period_s', value=-0.1),
        Parameter('flush_period_s', value=0.5),
        Parameter('storage', value='zip'),
        Parameter('queue_depth', value=2.5),
        Parameter('output_dir', value=''),
        Parameter('topics', value=[1, 2]),
    ],
)
def test_the_node_refuses_bad_parameters_with_their_name(override):
    rclpy.init()
    try:
        with pytest.raises(ParameterError, match=override.name):
            RecorderNode(parameter_overrides=[override])
    finally:
        rclpy.try_shutdown()
