"""Counters of what an input stage saw: every status topic counter comes from one of these."""
from __future__ import annotations

from dataclasses import field, fields
from typing import Any


def count(doc: str) -> Any:
    """A counter field, starting at 0, and what it counts (for the generated reference)."""
    return field(default=0, metadata={"doc": doc})


class Counters:
    """Base of the counter dataclasses: their fields, by name, as the status topic's map."""

    __slots__ = ()

    def as_dict(self, prefix: str = "") -> dict[str, int]:
        return {prefix + f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def docs(cls, prefix: str = "") -> dict[str, str]:
        """What each counter counts, by its status name."""
        return {prefix + f.name: f.metadata.get("doc", "") for f in fields(cls)}
