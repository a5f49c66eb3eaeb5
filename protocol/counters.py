"""Counters of what an input stage saw: every status topic counter comes from one of these."""
from __future__ import annotations

from dataclasses import fields


class Counters:
    """Base of the counter dataclasses: their fields, by name, as the status topic's map."""

    __slots__ = ()

    def as_dict(self, prefix: str = "") -> dict[str, int]:
        return {prefix + f.name: getattr(self, f.name) for f in fields(self)}
