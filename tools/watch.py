"""``sinsalign watch``: a live terminal view of every unit's attitude, σ, phase and counters.

A plain Zenoh subscriber (any number can run): it reads ``<prefix>/*/attitude`` and
``<prefix>/*/status`` and the liveliness tokens, and redraws a table a few times a second.

Anyone on the Zenoh network can publish under those keys, so what the decoders let through is shown field by
field: a field of the wrong type shows as "?" (a counter of the wrong type is left out of the sum, which then
shows as a lower bound, "≥N"), a message that does not decode is counted, and text from the wire is shown as
plain characters (no rich markup, control characters such as ESC shown as "?") so it cannot change the terminal.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh
from rich.table import Table
from rich.text import Text
from sinsalign.protocol import messages
from sinsalign.protocol.keys import UnitKeys

DECODERS = {"attitude": messages.decode_attitude, "status": messages.decode_status}


@dataclass(slots=True)
class UnitView:
    """The latest attitude and status one unit published, as decoded, and how many of its messages did not."""

    attitude: dict | None = None
    status: dict | None = None
    alive: bool = False
    bad_messages: int = 0

    def take(self, slot: str, payload: bytes) -> None:
        """``payload`` (msgpack) as the latest message of ``slot`` ("attitude" or "status"); one that does not
        decode is counted and the last good one stays."""
        try:
            setattr(self, slot, DECODERS[slot](payload))
        except messages.MessageError:
            self.bad_messages += 1


@dataclass(slots=True)
class WatchClient:
    """Keeps the latest attitude and status of every unit under ``keys.prefix`` (``only_unit``: of ``keys.unit``)."""

    session: zenoh.Session
    keys: UnitKeys
    only_unit: bool = False
    units: dict[str, UnitView] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _entities: list = field(default_factory=list)

    def __post_init__(self) -> None:
        units = f"{self.keys.prefix}/{self.keys.unit}" if self.only_unit else self.keys.all_units
        self._entities = [
            self.session.declare_subscriber(f"{units}/attitude", self._on_attitude),
            self.session.declare_subscriber(f"{units}/status", self._on_status),
            self.session.liveliness().declare_subscriber(f"{units}/alive", self._on_alive, history=True),
        ]

    def _unit(self, key: zenoh.KeyExpr) -> UnitView:
        name = str(key).split("/")[-2]
        return self.units.setdefault(name, UnitView())

    def _on_attitude(self, sample: zenoh.Sample) -> None:
        self._store(sample, "attitude")

    def _on_status(self, sample: zenoh.Sample) -> None:
        self._store(sample, "status")

    def _store(self, sample: zenoh.Sample, slot: str) -> None:
        with self._lock:
            self._unit(sample.key_expr).take(slot, sample.payload.to_bytes())

    def _on_alive(self, sample: zenoh.Sample) -> None:
        with self._lock:
            self._unit(sample.key_expr).alive = sample.kind == zenoh.SampleKind.PUT

    def table(self) -> Table:
        with self._lock:
            return units_table(self.keys.prefix, self.units)

    def close(self) -> None:
        for entity in self._entities:
            entity.undeclare()


ROWS = ("alive", "t (s)", "phase", "heading (°)", "heading σ (°)", "pitch (°)", "roll (°)", "level σ (°)",
        "converged", "health", "frames", "drops and faults", "loop p99 / max (ms)", "last error")


def units_table(prefix: str, units: dict[str, UnitView]) -> Table:
    """One column per unit, one row per quantity (fits an 80-column terminal)."""
    table = Table(title=Text(f"sinsalign units under '{_printable(prefix)}'"))
    table.add_column("")
    views = sorted(units.items())
    for name, _ in views:
        table.add_column(Text(_printable(name)), justify="right")
    for label, *cells in zip(ROWS, *(_column(view) for _, view in views), strict=True):
        table.add_row(label, *(Text(cell) for cell in cells))
    return table


def _column(view: UnitView) -> list[str]:
    a, s = view.attitude or {}, view.status or {}
    raw = s.get("counters")
    counters = raw if isinstance(raw, dict) else {}
    valid = {k: v for k, v in counters.items() if type(k) is str and type(v) is int and v >= 0}
    drops = messages.fault_count(valid) + view.bad_messages
    whole = len(valid) == len(raw) if isinstance(raw, dict) else raw is None
    loop = s.get("loop") if isinstance(s.get("loop"), dict) else {}
    return ["yes" if view.alive else "no", _num(a.get("t"), ".1f"), _text(a.get("phase"), 16),
            _num(a.get("heading_deg"), ".4f"), _num(a.get("heading_sigma_deg"), ".4f"), _num(a.get("pitch_deg"), ".4f"),
            _num(a.get("roll_deg"), ".4f"), _num(a.get("level_sigma_deg"), ".4f"), _cell(a.get("converged"), (bool,)),
            _text(s.get("health"), 16), _cell(counters.get("samples_used"), (int,)),
            str(drops) if whole else f"≥{drops}",
            f'{_num(loop.get("p99_ms"), ".2f")} / {_num(loop.get("max_ms"), ".2f")}', _text(s.get("last_error"), 48)]


def _cell(value: object, types: tuple[type, ...], show: Callable[[Any], str] = str) -> str:
    """A field as text: "-" when it is not there, "?" when it is not of ``types`` (exact types, as msgpack gives
    them: a bool is no number)."""
    if value is None:
        return "-"
    return show(value) if type(value) in types else "?"


def _num(value: object, fmt: str) -> str:
    return _cell(value, (int, float), lambda v: format(v, fmt))


def _text(value: object, width: int) -> str:
    return _cell(value, (str,), lambda v: _printable(v[:width]))


def _printable(text: str) -> str:
    return "".join(c if c.isprintable() else "?" for c in text)


def watch(client: WatchClient, duration_s: float | None = None, stop: threading.Event | None = None,
          refresh_hz: float = 4.0) -> None:
    """Redraw the table until Ctrl-C, ``duration_s`` or ``stop``."""
    from rich.live import Live
    end = None if duration_s is None else time.monotonic() + duration_s
    with Live(client.table(), refresh_per_second=refresh_hz, transient=False) as live:
        while (end is None or time.monotonic() < end) and not (stop is not None and stop.is_set()):
            time.sleep(1.0 / refresh_hz)
            live.update(client.table())
