"""drag_teach's parameters: the YAML file, the node's defaults and the solver's settings agree; bad ones are refused."""
import pathlib

import pytest
import rclpy
import yaml
from rclpy.parameter import Parameter

from stylepong_fdcc.drag_teach_node import PARAMETERS, DragTeachNode, quaternion_to_rotation, typed_parameter
from stylepong_fdcc.fdcc import FdccConfig

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'drag_teach.yaml'


def test_the_yaml_file_holds_every_parameter_with_the_node_default():
    values = yaml.safe_load(CONFIG.read_text())['drag_teach']['ros__parameters']
    assert set(values) == set(PARAMETERS)
    for name, (default, _) in PARAMETERS.items():
        assert values[name] == default, name


def test_every_solver_setting_is_a_parameter():
    derived = {'nominal_period_s'}   # from control_rate_hz
    assert set(FdccConfig.__dataclass_fields__) - derived <= set(PARAMETERS)


def test_integers_pass_for_floats_and_wrong_types_are_refused():
    assert typed_parameter('control_rate_hz', 250, 500.0) == 250.0
    assert typed_parameter('damping', [30, 30, 30, 3, 3, 3], [30.0] * 6) == [30.0, 30.0, 30.0, 3.0, 3.0, 3.0]
    with pytest.raises(ValueError, match='control_rate_hz'):
        typed_parameter('control_rate_hz', 'fast', 500.0)
    with pytest.raises(ValueError, match='start_enabled'):
        typed_parameter('start_enabled', 1, True)


@pytest.mark.parametrize('override', [Parameter('damping', value=[30.0, 30.0, 30.0]),
                                      Parameter('dynamics_model', value='heavy'),
                                      Parameter('control_rate_hz', value=5.0),
                                      Parameter('max_force_n', value=-1.0)])
def test_the_node_refuses_bad_parameters_with_their_name(override):
    rclpy.init()
    try:
        with pytest.raises(ValueError, match=override.name.split('_')[0]):
            DragTeachNode(parameter_overrides=[override])
    finally:
        rclpy.try_shutdown()


def test_quaternions_are_normalised_and_degenerate_ones_refused():
    assert quaternion_to_rotation(0.0, 0.0, 0.0, 2.0).tolist() == [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    assert quaternion_to_rotation(0.0, 0.0, 0.0, 0.0) is None
    assert quaternion_to_rotation(float('nan'), 0.0, 0.0, 1.0) is None
