"""Results as JSON Lines (docs/reference.md, "Results"): one object per output epoch.

Fields: t (s), phase, q = [w, x, y, z] of C_b^n(t), pitch_deg, roll_deg, heading_deg (0-360,
clockwise from true North), heading_sigma_deg, level_sigma_deg, converged; plus diagnostics
(rho, trace_P, n_obs) that the pin allows; transfer alignment adds mount_q = [w, x, y, z] of the
slave-to-master mounting C_bs^bm and its 1-sigma mount_sigma_deg (largest axis).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

PHASES = ("coarse", "fine", "aligned", "disturbed")
PINNED_FIELDS = ("t", "phase", "q", "pitch_deg", "roll_deg", "heading_deg", "heading_sigma_deg",
                 "level_sigma_deg", "converged")


@dataclass(frozen=True, slots=True)
class ResultRecord:
    t: float
    phase: str
    q: tuple[float, float, float, float]
    pitch_deg: float
    roll_deg: float
    heading_deg: float
    heading_sigma_deg: float
    level_sigma_deg: float
    converged: bool
    rho: float
    trace_P: float
    n_obs: int
    mount_q: tuple[float, float, float, float] | None = None
    mount_sigma_deg: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """The fields, without the mounting's where there is none (every mode but transfer alignment)."""
        names = self.__slots__ if self.mount_q is not None or self.mount_sigma_deg is not None else _PLAIN_FIELDS
        return {name: getattr(self, name) for name in names
                if not (name.startswith("mount_") and getattr(self, name) is None)}

    def wire_dict(self) -> dict[str, Any]:
        """The fields as JSON and msgpack carry them: lists for quaternions, None for a non-finite trace_P."""
        d = self.as_dict()
        d["q"] = list(self.q)
        if self.mount_q is not None:
            d["mount_q"] = list(self.mount_q)
        if not math.isfinite(d["trace_P"]):
            d["trace_P"] = None  # no observation yet; JSON has no infinity
        return d

    @property
    def finite(self) -> bool:
        """Every number is finite (trace_P excepted: infinite before the first observation, carried as null)."""
        if self._plain_numbers() is not None:   # every record of every mode but transfer alignment's: one sum
            return True
        return all(_finite(getattr(self, name)) for name in self.__slots__ if name != "trace_P")

    def _plain_numbers(self) -> tuple[float, ...] | None:
        """t, q, pitch, roll, heading, the two σ and rho, when the record has no mounting and each is a float and
        finite (their sum is: a NaN or an infinity anywhere makes it one), else None."""
        numbers = (self.t, *self.q, self.pitch_deg, self.roll_deg, self.heading_deg, self.heading_sigma_deg,
                   self.level_sigma_deg, self.rho)
        if (self.mount_q is None and self.mount_sigma_deg is None and all(type(x) is float for x in numbers)
                and math.isfinite(sum(numbers))):
            return numbers
        return None

    def to_json(self) -> str:
        """One line of strict JSON. A number that is not finite (trace_P aside, carried as null) is a fault upstream;
        it is refused here, naming the fields, rather than written as NaN or Infinity, which no JSON reader takes.
        A record of plain finite floats (every mode's but transfer alignment's) is formatted directly, as the encoder
        writes it (float's repr, the pinned field order)."""
        numbers = self._plain_numbers()
        if (numbers is not None and self.phase in PHASES and type(self.n_obs) is int
                and type(self.converged) is bool and type(self.trace_P) is float):
            t, w, x, y, z, pitch, roll, heading, heading_sigma, level_sigma, rho = numbers
            trace_P = repr(self.trace_P) if math.isfinite(self.trace_P) else "null"
            return (f'{{"t":{t!r},"phase":"{self.phase}","q":[{w!r},{x!r},{y!r},{z!r}],"pitch_deg":{pitch!r},'
                    f'"roll_deg":{roll!r},"heading_deg":{heading!r},"heading_sigma_deg":{heading_sigma!r},'
                    f'"level_sigma_deg":{level_sigma!r},"converged":{"true" if self.converged else "false"},'
                    f'"rho":{rho!r},"trace_P":{trace_P},"n_obs":{self.n_obs}}}')
        return self._encoded()

    def _encoded(self) -> str:
        """:meth:`to_json` through the JSON encoder (any record)."""
        d = self.wire_dict()
        try:
            return _ENCODER.encode(d)
        except ValueError:
            bad = _non_finite(d)
            if not bad:
                raise
            raise ValueError(f"result at t = {self.t!r}: {', '.join(bad)} not finite; not written") from None


_PLAIN_FIELDS = tuple(name for name in ResultRecord.__slots__ if not name.startswith("mount_"))
_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False)
"""json.dumps' encoder for these arguments, made once (dumps makes one per call)."""


def _non_finite(wire: dict[str, Any]) -> list[str]:
    """The fields of a wire dict that hold a number that is not finite."""
    return [name for name, value in wire.items() if not _finite(value)]


def _finite(value: Any) -> bool:
    """Whether a field (or its wire form) holds finite numbers only (texts, booleans and null hold none)."""
    if isinstance(value, list | tuple):
        return all(_finite(v) for v in value)
    return not isinstance(value, float) or math.isfinite(value)


def validate_result(row: Any) -> list[str]:
    """Problems of one decoded result object against the pin (empty list when it conforms)."""
    if not isinstance(row, dict):
        return ["not an object"]
    problems = [f"missing {name}" for name in PINNED_FIELDS if name not in row]
    if problems:
        return problems
    for name in ("t", "pitch_deg", "roll_deg", "heading_deg", "heading_sigma_deg", "level_sigma_deg"):
        v = row[name]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            problems.append(f"{name} not a finite number")
    if row["phase"] not in PHASES:
        problems.append(f"phase {row['phase']!r} not one of {PHASES}")
    if not isinstance(row["converged"], bool):
        problems.append("converged not a boolean")
    q = row["q"]
    if not (isinstance(q, list) and len(q) == 4 and all(isinstance(c, int | float) for c in q)):
        problems.append("q not four numbers")
    elif abs(math.sqrt(sum(c * c for c in q)) - 1.0) > 1e-9:
        problems.append("q not a unit quaternion")
    if not problems and not 0.0 <= row["heading_deg"] < 360.0:
        problems.append("heading_deg outside [0, 360)")
    return problems
