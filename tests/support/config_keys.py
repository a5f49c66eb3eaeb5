"""Configuration keys by their dotted table (``aiding.odo``), for tests that walk or set every key."""
from typing import Any


def in_table(table: str, values: dict[Any, Any]) -> dict[str, Any]:
    """{"aiding": {"odo": values}} for table ``aiding.odo``: the mapping that sets ``values`` in that table."""
    out: dict[str, Any] = values
    for part in reversed(table.split(".")):
        out = {part: out}
    return out


def one_key(table: str, key: str, value: Any) -> dict[str, Any]:
    """The mapping that sets one key of a table (:func:`in_table`)."""
    return in_table(table, {key: value})
