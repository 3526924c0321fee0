"""Test helper: every string in a JSON document, keys included (to look for machine paths in it)."""

from typing import Any, Iterator


def json_strings(value: Any) -> Iterator[str]:
    """Every key and string value of a parsed JSON document, depth first."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield str(key)
            yield from json_strings(item)
    elif isinstance(value, list):
        for item in value:
            yield from json_strings(item)
    elif isinstance(value, str):
        yield value
