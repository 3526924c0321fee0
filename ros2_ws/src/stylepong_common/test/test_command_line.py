"""command_line: how a tool ends on Ctrl-C, its count checks and its JSON summary (no ROS)."""

import argparse
import json

import pytest

from stylepong_common.command_line import (
    exit_with_run,
    print_and_write_json,
    require_counts,
    write_lines,
)
from stylepong_common.exit_codes import EXIT_INTERRUPTED


def interrupted(argv):
    raise KeyboardInterrupt


@pytest.mark.parametrize(
    'run, status, error',
    [
        (lambda argv: len(argv), 2, ''),
        (interrupted, EXIT_INTERRUPTED, 'tool: interrupted, nothing written\n'),
    ],
)
def test_the_exit_status_is_the_run_s_or_130_on_ctrl_c(capsys, run, status, error):
    with pytest.raises(SystemExit) as exited:
        exit_with_run('tool', run, ['a', 'b'])
    assert exited.value.code == status and capsys.readouterr().err == error


def test_a_count_below_one_stops_the_parser_naming_the_option_as_typed(capsys):
    parser = argparse.ArgumentParser(prog='tool')
    parser.add_argument('--seeds', type=int, default=1)
    parser.add_argument('--num-threads', type=int, default=1)
    require_counts(parser, parser.parse_args([]), ('seeds', 'num_threads'))
    with pytest.raises(SystemExit) as exited:
        require_counts(parser, parser.parse_args(['--num-threads', '0']), ('seeds', 'num_threads'))
    assert exited.value.code == 2 and 'tool: error: --num-threads must be at least 1' in capsys.readouterr().err


def test_the_summary_printed_is_the_one_written(tmp_path, capsys):
    summary = {'success': 0.5, 'seeds': [900, 901]}
    print_and_write_json(summary, tmp_path / 'new' / 'summary.json')
    printed = capsys.readouterr().out
    assert json.loads(printed) == summary == json.loads((tmp_path / 'new' / 'summary.json').read_text())
    print_and_write_json(summary, None)
    assert capsys.readouterr().out == printed


def test_lines_are_written_with_a_final_newline_and_the_path_said(tmp_path, capsys):
    write_lines(tmp_path / 'new' / 'table.md', ['# Title', '', '| a |'])
    assert (tmp_path / 'new' / 'table.md').read_text() == '# Title\n\n| a |\n'
    assert capsys.readouterr().out == f'wrote {tmp_path / "new" / "table.md"}\n'
