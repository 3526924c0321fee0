"""config/virtual_teacher.yaml lists every virtual_teacher parameter with the node's default; `seed` picks the take."""
import pathlib

import pytest
import rclpy
import yaml

from stylepong_common.node_support import ParameterError
from stylepong_sim.teacher import SwingVariation, sample_variation
from stylepong_sim.virtual_teacher_node import PARAMETERS, VirtualTeacherNode

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'virtual_teacher.yaml'


def _node(*ros_args: str) -> tuple[VirtualTeacherNode, rclpy.Context]:
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', *ros_args], context=context)
    return VirtualTeacherNode(context=context), context


def _close(node, context) -> None:
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_the_yaml_holds_every_parameter_with_the_nodes_default():
    in_yaml = yaml.safe_load(CONFIG.read_text())['virtual_teacher']['ros__parameters']
    assert list(in_yaml) == [row.name for row in PARAMETERS]
    for row in PARAMETERS:
        assert in_yaml[row.name] == row.default and type(in_yaml[row.name]) is type(row.default), row.name
    node, context = _node('--params-file', str(CONFIG))
    try:
        assert node.p == {row.name: row.default for row in PARAMETERS}
    finally:
        _close(node, context)


@pytest.mark.parametrize('swing', ['forward', 'rightward'])
def test_the_seed_parameter_picks_the_take_and_variation_zero_is_the_nominal_stroke(swing):
    node, context = _node('-p', f'swing:={swing}', '-p', 'seed:=5')
    try:
        assert node.teacher.path.variation == sample_variation(swing, 5)
    finally:
        _close(node, context)
    node, context = _node('-p', f'swing:={swing}', '-p', 'seed:=5', '-p', 'variation:=0.0')
    try:
        assert node.teacher.path.variation == SwingVariation()
    finally:
        _close(node, context)


@pytest.mark.parametrize('override', ['seed:=-1', 'variation:=1.5', 'seed:=2.0', 'swing:=sideways', 'rate_hz:=5.0',
                                      'lead_in_s:=-1.0', 'grip_frame:=nowhere'])
def test_a_bad_parameter_is_refused_in_one_line_naming_it(override):
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '-p', override], context=context)
    try:
        with pytest.raises(ParameterError) as error:
            VirtualTeacherNode(context=context)
        assert override.split(':=')[0] in str(error.value) and '\n' not in str(error.value)
    finally:
        rclpy.try_shutdown(context=context)


def test_a_reach_beyond_the_sides_limit_is_refused_naming_it():
    """side_reach_m's bound depends on the swing (the left's reach ends sooner): checked with the swing."""
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '-p', 'swing:=leftward', '-p', 'side_reach_m:=0.2'], context=context)
    try:
        with pytest.raises(ParameterError, match='side_reach_m') as error:
            VirtualTeacherNode(context=context)
        assert '\n' not in str(error.value)
    finally:
        rclpy.try_shutdown(context=context)
    node, context = _node('-p', 'swing:=rightward', '-p', 'side_reach_m:=0.2')
    try:
        assert node.teacher.path.config.side_reach_m == 0.2
    finally:
        _close(node, context)
