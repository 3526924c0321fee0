"""parameter_files: a parameter file read for one node, and how it differs from the node's table."""

from stylepong_common.node_support import Param
from stylepong_common.parameter_files import differences_from_defaults, file_parameters

TABLE = (Param('rate_hz', 60.0, ''), Param('name', 'a', ''))


def test_the_file_gives_the_nodes_parameters_in_its_order(tmp_path):
    path = tmp_path / 'node.yaml'
    path.write_text('node:\n  ros__parameters:\n    rate_hz: 60.0\n    name: a\nother:\n  ros__parameters: {}\n')
    assert list(file_parameters(path, 'node').items()) == [('rate_hz', 60.0), ('name', 'a')]


def test_a_file_with_every_default_has_no_differences():
    assert differences_from_defaults(TABLE, {'rate_hz': 60.0, 'name': 'a'}) == []


def test_missing_or_reordered_names_are_one_difference():
    assert len(differences_from_defaults(TABLE, {'name': 'a', 'rate_hz': 60.0})) == 1
    assert len(differences_from_defaults(TABLE, {'rate_hz': 60.0})) == 1


def test_another_value_or_type_is_named():
    assert differences_from_defaults(TABLE, {'rate_hz': 60, 'name': 'b'}) == [
        'rate_hz: 60 is not the default 60.0',
        "name: 'b' is not the default 'a'",
    ]
