"""Nodes in rclpy contexts of their own, made from command-line arguments and dropped again: what the tests of
a node's parameters share (a context of its own per node, so nothing is left initialised in the process's
default context between tests).

    with node_in_context(VirtualTeacherNode, '-p', 'seed:=5') as node:      # node.destroy_node() on leaving
        ...
    with ros_context('-p', 'seed:=-1') as context, pytest.raises(ParameterError):
        VirtualTeacherNode(context=context)
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import TypeVar

import rclpy
from rclpy.node import Node

NodeT = TypeVar('NodeT', bound=Node)


@contextlib.contextmanager
def ros_context(*ros_args: str) -> Iterator[rclpy.Context]:
    """A context initialised with these --ros-args (e.g. '-p', 'name:=value'), shut down on leaving."""
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', *ros_args], context=context)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@contextlib.contextmanager
def node_in_context(make_node: Callable[..., NodeT], *ros_args: str) -> Iterator[NodeT]:
    """make_node(context=...) in a ros_context(*ros_args); the node is destroyed on leaving (a node that
    holds more, such as a simulator, is closed by its caller first, e.g. with contextlib.closing)."""
    with ros_context(*ros_args) as context:
        node = make_node(context=context)
        try:
            yield node
        finally:
            node.destroy_node()
