"""Markdown that the workspace's reports and benchmark sections write (no rclpy): tables of text cells."""

from __future__ import annotations

from collections.abc import Sequence


def table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A Markdown table's lines: the header, the separator under it (one column per header cell), a line
    per row."""
    lines = [row(header), '|' + '|'.join('---' for _ in header) + '|']
    return lines + [row(cells) for cells in rows]


def row(cells: Sequence[str]) -> str:
    """One line of a Markdown table (for a table printed a row at a time, under `table(header, [])`)."""
    return '| ' + ' | '.join(cells) + ' |'
