"""config/virtual_teacher.yaml lists every virtual_teacher parameter with the node's default; `seed` picks the take."""

import pathlib

import pytest

from stylepong_common.node_context import node_in_context, ros_context
from stylepong_common.node_support import ParameterError
from stylepong_common.parameter_files import differences_from_defaults, file_parameters
from stylepong_sim.nodes.virtual_teacher_node import PARAMETERS, VirtualTeacherNode
from stylepong_sim.teaching.teacher import SwingVariation, sample_variation

CONFIG = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'virtual_teacher.yaml'


def test_the_yaml_holds_every_parameter_with_the_nodes_default():
    assert differences_from_defaults(PARAMETERS, file_parameters(CONFIG, 'virtual_teacher')) == []
    with node_in_context(VirtualTeacherNode, '--params-file', str(CONFIG)) as node:
        assert node.p == {row.name: row.default for row in PARAMETERS}


@pytest.mark.parametrize('swing', ['forward', 'rightward'])
def test_the_seed_parameter_picks_the_take_and_variation_zero_is_the_nominal_stroke(swing):
    with node_in_context(VirtualTeacherNode, '-p', f'swing:={swing}', '-p', 'seed:=5') as node:
        assert node.teacher.path.variation == sample_variation(swing, 5)
    with node_in_context(VirtualTeacherNode, '-p', f'swing:={swing}', '-p', 'seed:=5', '-p', 'variation:=0.0') as node:
        assert node.teacher.path.variation == SwingVariation()


@pytest.mark.parametrize(
    'override',
    [
        'seed:=-1',
        'variation:=1.5',
        'seed:=2.0',
        'swing:=sideways',
        'rate_hz:=5.0',
        'lead_in_s:=-1.0',
        'grip_frame:=nowhere',
    ],
)
def test_a_bad_parameter_is_refused_in_one_line_naming_it(override):
    with ros_context('-p', override) as context, pytest.raises(ParameterError) as error:
        VirtualTeacherNode(context=context)
    assert override.split(':=')[0] in str(error.value) and '\n' not in str(error.value)


def test_a_reach_beyond_the_sides_limit_is_refused_naming_it():
    """side_reach_m's bound depends on the swing (the left's reach ends sooner): checked with the swing."""
    with ros_context('-p', 'swing:=leftward', '-p', 'side_reach_m:=0.2') as context:
        with pytest.raises(ParameterError, match='side_reach_m') as error:
            VirtualTeacherNode(context=context)
    assert '\n' not in str(error.value)
    with node_in_context(VirtualTeacherNode, '-p', 'swing:=rightward', '-p', 'side_reach_m:=0.2') as node:
        assert node.teacher.path.config.side_reach_m == 0.2
