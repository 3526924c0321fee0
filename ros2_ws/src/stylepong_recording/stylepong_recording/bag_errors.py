"""How reading a bag fails: `BagError` and the one-line reasons it carries (no rclpy)."""

from __future__ import annotations

REASON_MAX_CHARS = 240


class BagError(Exception):
    """A bag (or topic) that cannot be used; the message is a one-line reason for a person."""


def one_line(error: BaseException | str, max_chars: int = REASON_MAX_CHARS) -> str:
    """First line of an error, shortened: rosbags' messages can carry whole schema texts."""
    text = str(error).strip() or type(error).__name__
    if isinstance(error, BaseException) and not isinstance(error, BagError) and type(error).__name__ not in text:
        text = f'{type(error).__name__}: {text}'
    line = text.splitlines()[0] if text else ''
    return line if len(line) <= max_chars else line[: max_chars - 3] + '...'
