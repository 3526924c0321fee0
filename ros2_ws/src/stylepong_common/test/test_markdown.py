"""markdown: tables as the reports and benchmarks print them."""

from stylepong_common.markdown import row, table


def test_a_table_has_its_header_a_separator_per_column_and_a_line_per_row():
    assert table(['a', 'b'], [['1', '2'], ['3', '']]) == ['| a | b |', '|---|---|', '| 1 | 2 |', '| 3 |  |']


def test_a_table_without_rows_is_its_header():
    assert table(['only'], []) == ['| only |', '|---|']


def test_a_row_is_a_line_of_the_table():
    assert row(['1', '2']) == table(['a', 'b'], [['1', '2']])[2]
