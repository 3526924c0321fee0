"""drag_teach's parameters: the YAML file, the node's table and the solver's settings agree; bad ones are
refused in one line naming them, with stylepong_common's exit code."""

import pathlib

import pytest
import rclpy
from rclpy.parameter import Parameter

from stylepong_common.node_support import ParameterError
from stylepong_common.parameter_files import differences_from_defaults, file_parameters
from stylepong_fdcc.drag_teach_node import PARAMETERS, DragTeachNode, quaternion_to_rotation
from stylepong_fdcc.fdcc_config import FdccConfig

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'drag_teach.yaml'


def test_the_yaml_file_holds_every_parameter_with_the_node_default():
    assert differences_from_defaults(PARAMETERS, file_parameters(CONFIG, 'drag_teach')) == []


def test_every_solver_setting_is_a_parameter():
    derived = {'nominal_period_s'}  # from control_rate_hz
    assert set(FdccConfig.__dataclass_fields__) - derived <= {row.name for row in PARAMETERS}


def test_integers_pass_for_floats_and_the_node_builds_its_config_from_them():
    rclpy.init()
    try:
        node = DragTeachNode(
            parameter_overrides=[
                Parameter('control_rate_hz', value=250),
                Parameter('damping', value=[30, 30, 30, 3, 3, 3]),
            ]
        )
        assert node.controller.config.nominal_period_s == 1.0 / 250.0
        assert node.controller.config.damping == (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
        node.destroy_node()
    finally:
        rclpy.try_shutdown()


@pytest.mark.parametrize(
    'override',
    [
        Parameter('damping', value=[30.0, 30.0, 30.0]),
        Parameter('damping', value=[0.0] * 6),
        Parameter('dynamics_model', value='heavy'),
        Parameter('control_rate_hz', value=5.0),
        Parameter('control_rate_hz', value='fast'),
        Parameter('start_enabled', value=1),
        Parameter('max_force_n', value=-1.0),
        Parameter('max_force_n', value=600.0),
    ],
)
def test_the_node_refuses_bad_parameters_with_their_name(override):
    rclpy.init()
    try:
        with pytest.raises(ParameterError, match=override.name.split('_')[0]):
            DragTeachNode(parameter_overrides=[override])
    finally:
        rclpy.try_shutdown()


def test_quaternions_are_normalised_and_degenerate_ones_refused():
    assert quaternion_to_rotation(0.0, 0.0, 0.0, 2.0).tolist() == [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    assert quaternion_to_rotation(0.0, 0.0, 0.0, 0.0) is None
    assert quaternion_to_rotation(float('nan'), 0.0, 0.0, 1.0) is None
