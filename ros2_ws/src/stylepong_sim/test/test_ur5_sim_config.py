"""config/ur5_sim.yaml lists every ur5_sim parameter with the node's default; realistic_sensing.yaml is valid;
bad values are refused in one line naming the parameter, at start-up and (real_time_factor) at run time."""

import contextlib
import math
import pathlib
from collections.abc import Iterator

import pytest
from rclpy.parameter import Parameter

from stylepong_common.node_context import node_in_context, ros_context
from stylepong_common.node_support import ParameterError
from stylepong_common.parameter_files import file_parameters
from stylepong_sim import world_spec
from stylepong_sim.nodes.ur5_sim_node import PARAMETERS, Ur5SimNode

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config'


def _yaml_parameters(name: str) -> dict:
    return file_parameters(CONFIG / name, 'ur5_sim')


@contextlib.contextmanager
def _node(*ros_args: str) -> Iterator[Ur5SimNode]:
    """The node, closed (its cell and video) before it is destroyed."""
    with node_in_context(Ur5SimNode, *ros_args) as node, contextlib.closing(node):
        yield node


def test_the_yaml_holds_every_parameter_with_its_default():
    with _node() as node:
        declared = {
            name: p.value
            for name, p in node._parameters.items()
            if name not in ('use_sim_time', 'start_type_description_service')
        }
    in_yaml = _yaml_parameters('ur5_sim.yaml')
    assert set(in_yaml) == set(declared)
    for name, value in in_yaml.items():
        default = declared[name]
        if isinstance(default, (list, tuple)) or hasattr(default, 'tolist'):
            assert list(value) == pytest.approx(list(default)), name
        else:
            assert value == default, name
    assert in_yaml['home_joint_positions_rad'] == pytest.approx(list(world_spec.HOME_JOINT_POSITIONS_RAD))
    assert in_yaml['real_time_factor'] == 1.0


def test_realistic_sensing_is_valid_and_not_perfect():
    realistic = _yaml_parameters('realistic_sensing.yaml')
    with _node('--params-file', str(CONFIG / 'realistic_sensing.yaml')) as node:
        for name, value in realistic.items():
            assert node.get_parameter(name).value == pytest.approx(value), name
    for name in ('ball_position_noise_std_m', 'ball_latency_s', 'ball_dropout_probability', 'ft_force_noise_std_n'):
        assert realistic[name] > 0.0
    assert any(v != 0.0 for v in realistic['ft_force_bias_n'])


def test_tracker_sensing_is_valid_and_reports_positions_only():
    tracker = _yaml_parameters('tracker_sensing.yaml')
    with _node('--params-file', str(CONFIG / 'tracker_sensing.yaml')) as node:
        for name, value in tracker.items():
            assert node.get_parameter(name).value == pytest.approx(value), name
        assert node._camera is None  # no /ball/state from the cell: ball_estimator's job
    for name in (
        'ball_detection_latency_s',
        'ball_detection_noise_std_m',
        'ball_detection_dropout_probability',
        'ball_detection_outlier_probability',
    ):
        assert tracker[name] > 0.0
    assert tracker['ball_detection_rate_hz'] == 150.0


def test_the_table_names_every_parameter_in_the_yaml_order():
    assert [row.name for row in PARAMETERS] == list(_yaml_parameters('ur5_sim.yaml'))


@pytest.mark.parametrize(
    'args, name',
    [
        (('-p', 'real_time_factor:=-1.0'), 'real_time_factor'),
        (('-p', 'ball_latency_s:=-0.5'), 'ball_latency_s'),
        (('-p', 'home_joint_positions_rad:=[0.0,0.0]'), 'home_joint_positions_rad'),
        (('-p', 'home_joint_positions_rad:=[9.0,0.0,0.0,0.0,0.0,0.0]'), 'home_joint_positions_rad'),
        (('-p', 'ft_force_bias_n:=[1.0]'), 'ft_force_bias_n'),
        (('-p', 'sensing_seed:=-3'), 'sensing_seed'),
        (('-p', 'ball_detection_latency_jitter_s:=0.5'), 'ball_detection_latency_jitter_s'),
        (('-p', 'ball_camera_xyz_m:=[0.0,1.0]'), 'ball_camera_xyz_m'),
        (('-p', 'video_width:=8.0'), 'video_width'),
    ],
)
def test_bad_parameters_stop_the_node_with_one_line_naming_them(args, name):
    with ros_context(*args) as context, pytest.raises(ParameterError) as error:
        Ur5SimNode(context=context)
    assert name in str(error.value) and '\n' not in str(error.value)


def test_real_time_factor_changes_at_run_time_within_its_bounds_only():
    with _node() as node:
        assert node.set_parameters([Parameter('real_time_factor', value=2)])[0].successful
        assert node._real_time_factor == 2.0
        refused = node.set_parameters([Parameter('real_time_factor', value=101.0)])[0]
        assert not refused.successful and 'real_time_factor' in refused.reason
        assert node._real_time_factor == 2.0
        assert not node.set_parameters([Parameter('max_lag_s', value=1.0)])[0].successful  # read-only


def test_an_integer_real_time_factor_is_accepted():
    with _node('-p', 'real_time_factor:=0') as node:
        assert node._real_time_factor == 0.0 and not math.isnan(node._real_time_factor)
