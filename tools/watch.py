"""``sinsalign watch``: a live terminal view of every unit's attitude, σ, phase and counters.

A plain Zenoh subscriber (any number can run): it reads ``<prefix>/*/attitude`` and
``<prefix>/*/status`` and the liveliness tokens, and redraws a table a few times a second.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import zenoh
from rich.table import Table
from sinsalign.protocol import messages
from sinsalign.protocol.keys import UnitKeys


@dataclass(slots=True)
class UnitView:
    attitude: dict | None = None
    status: dict | None = None
    alive: bool = False
    bad_messages: int = 0


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
        self._store(sample, messages.decode_attitude, "attitude")

    def _on_status(self, sample: zenoh.Sample) -> None:
        self._store(sample, messages.decode_status, "status")

    def _store(self, sample: zenoh.Sample, decode, slot: str) -> None:
        with self._lock:
            view = self._unit(sample.key_expr)
            try:
                setattr(view, slot, decode(sample.payload.to_bytes()))
            except messages.MessageError:
                view.bad_messages += 1

    def _on_alive(self, sample: zenoh.Sample) -> None:
        with self._lock:
            self._unit(sample.key_expr).alive = sample.kind == zenoh.SampleKind.PUT

    def table(self) -> Table:
        """One column per unit, one row per quantity (fits an 80-column terminal)."""
        table = Table(title=f"sinsalign units under '{self.keys.prefix}'")
        table.add_column("")
        with self._lock:
            views = sorted(self.units.items())
            for name, _ in views:
                table.add_column(name, justify="right")
            rows = [[label] for label in ROWS]
            for _, view in views:
                for row, value in zip(rows, _column(view), strict=True):
                    row.append(value)
        for row in rows:
            table.add_row(*row)
        return table

    def close(self) -> None:
        for entity in self._entities:
            entity.undeclare()


ROWS = ("alive", "t (s)", "phase", "heading (°)", "heading σ (°)", "pitch (°)", "roll (°)", "level σ (°)",
        "converged", "health", "frames", "drops and faults", "last error")


def _column(view: UnitView) -> list[str]:
    a, s = view.attitude or {}, view.status or {}
    counters = s.get("counters", {})
    drops = messages.fault_count(counters) + view.bad_messages
    return ["yes" if view.alive else "no", _num(a.get("t"), ".1f"), a.get("phase", "-"),
            _num(a.get("heading_deg"), ".4f"), _num(a.get("heading_sigma_deg"), ".4f"), _num(a.get("pitch_deg"), ".4f"),
            _num(a.get("roll_deg"), ".4f"), _num(a.get("level_sigma_deg"), ".4f"), str(a.get("converged", "-")),
            s.get("health", "-"), str(counters.get("samples_used", "-")), str(drops), (s.get("last_error") or "")[:48]]


def _num(value: object, fmt: str) -> str:
    return "-" if not isinstance(value, int | float) else format(value, fmt)


def watch(client: WatchClient, duration_s: float | None = None, stop: threading.Event | None = None,
          refresh_hz: float = 4.0) -> None:
    """Redraw the table until Ctrl-C, ``duration_s`` or ``stop``."""
    from rich.live import Live
    end = None if duration_s is None else time.monotonic() + duration_s
    with Live(client.table(), refresh_per_second=refresh_hz, transient=False) as live:
        while (end is None or time.monotonic() < end) and not (stop is not None and stop.is_set()):
            time.sleep(1.0 / refresh_hz)
            live.update(client.table())
