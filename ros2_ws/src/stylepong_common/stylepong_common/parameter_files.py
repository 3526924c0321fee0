"""A node's shipped parameter file (config/<node>.yaml) held against its parameter table (node_support.Param
rows): what the nodes' tests check, so that the file a launch passes runs the node exactly as its defaults do.
"""

from __future__ import annotations

import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import yaml

from stylepong_common.node_support import Param


def file_parameters(path: pathlib.Path, node_name: str) -> dict[str, Any]:
    """The ros__parameters of `node_name` in a ROS 2 parameter file, in the file's order."""
    return yaml.safe_load(path.read_text())[node_name]['ros__parameters']


def differences_from_defaults(table: Sequence[Param], values: Mapping[str, Any]) -> list[str]:
    """How `values` differ from the table: names missing, extra or out of the table's order, and each value
    that is not the row's default or not of its type (an int for a float would change the parameter's
    type); [] when they agree."""
    names = [row.name for row in table]
    if list(values) != names:
        return [f"the names {list(values)} are not the table's {names}"]
    return [
        f'{row.name}: {values[row.name]!r} is not the default {row.default!r}'
        for row in table
        if values[row.name] != row.default or type(values[row.name]) is not type(row.default)
    ]
