"""node_context: a node in a context of its own, its --ros-args applied, everything shut down on leaving."""

import functools

import pytest
from rclpy.node import Node

from stylepong_common.node_context import node_in_context, ros_context


def _probe(context) -> Node:
    return Node('probe', context=context, automatically_declare_parameters_from_overrides=True)


def test_the_node_sees_its_arguments_and_its_context_is_shut_down_on_leaving():
    with node_in_context(_probe, '-p', 'rate_hz:=25.0') as node:
        assert node.get_parameter('rate_hz').value == 25.0
        context = node.context
        assert context.ok()
    assert not context.ok()


def test_a_node_that_fails_to_start_leaves_no_context_behind():
    contexts = []

    def refuse(context):
        contexts.append(context)
        raise ValueError('bad parameter')

    with pytest.raises(ValueError, match='bad parameter'):
        with node_in_context(refuse):
            pass
    assert not contexts[0].ok()


def test_a_context_alone_is_shut_down_on_leaving_even_after_an_error():
    with pytest.raises(RuntimeError):
        with ros_context() as context:
            assert context.ok()
            raise RuntimeError('the test failed')
    assert not context.ok()


def test_the_factory_gets_the_context_by_keyword():
    with node_in_context(functools.partial(Node, 'named')) as node:
        assert node.get_name() == 'named'
