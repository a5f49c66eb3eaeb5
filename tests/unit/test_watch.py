"""``sinsalign watch`` shows whatever a peer publishes without raising: field by field, as plain text.

GIVEN any msgpack map under a unit's attitude or status key (the pinned keys with values of any type), WHEN watch
takes it and draws its table, THEN nothing raises; the fields of the right type are shown, the others as "?",
a counter of the wrong type is left out of the drops (shown as a lower bound), and text from the wire reaches the
terminal neither as rich markup nor as control characters.
"""
from __future__ import annotations

import io

from hypothesis import given, settings
from hypothesis import strategies as st
from rich.console import Console
from sinsalign.protocol import messages
from sinsalign.tools.watch import ROWS, UnitView, units_table

VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-2**63, 2**64 - 1) | st.floats() | st.text(max_size=12)
    | st.binary(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=8)
NUMBERS = ("t", "pitch_deg", "roll_deg", "heading_deg", "heading_sigma_deg", "level_sigma_deg", "rho", "trace_P",
           "n_obs", "mount_sigma_deg")
NUMBER = st.floats(allow_nan=False, allow_infinity=False) | st.integers(-2**31, 2**31)
QUATERNION = st.lists(VALUES | NUMBER, min_size=4, max_size=4)
# each pinned key with a value of the right type or of any type, so that some maps pass the decoders
ATTITUDE = st.fixed_dictionaries(
    {"v": st.just(1) | VALUES, **{key: NUMBER | VALUES for key in NUMBERS[:6]},
     "q": QUATERNION | VALUES, "phase": st.sampled_from(["coarse", "fine", "[/]", "\x1b[2J"]) | VALUES},
    optional={"unit": VALUES, "converged": st.booleans() | VALUES, "mount_q": QUATERNION | VALUES,
              **{key: NUMBER | VALUES for key in NUMBERS[6:]}})
STATUS = st.fixed_dictionaries(
    {"v": st.just(1) | VALUES, "health": st.sampled_from(messages.HEALTH) | VALUES,
     "counters": st.dictionaries(st.text(max_size=12) | st.sampled_from(["samples_used", "seq_gaps"]),
                                 st.integers(0, 2**64 - 1) | VALUES, max_size=5) | VALUES},
    optional={**{key: VALUES for key in ("unit", "uptime_s", "phase", "t_last", "last_error")},
              "loop": st.fixed_dictionaries({}, optional={key: NUMBER | VALUES for key in ("p99_ms", "max_ms")})
              | VALUES})


def drawn(view: UnitView) -> str:
    """The table as the terminal gets it (ANSI codes on, as in a real terminal)."""
    out = io.StringIO()
    Console(file=out, width=80, force_terminal=True).print(units_table("sinsalign", {"u": view}))
    return out.getvalue()


def cells(view: UnitView) -> dict[str, str]:
    table = units_table("sinsalign", {"u": view})
    return dict(zip(ROWS, (str(cell) for cell in table.columns[1].cells), strict=True))


@settings(max_examples=100, deadline=None)
@given(attitude=ATTITUDE, status=STATUS)
def test_any_map_under_the_keys_is_drawn_without_raising(attitude: dict, status: dict) -> None:
    view = UnitView(alive=True)
    view.take("attitude", messages.pack(attitude))
    view.take("status", messages.pack(status))
    assert "\x1b[2J" not in drawn(view)
    view.attitude, view.status = attitude, status    # what a looser decoder would let through is drawn as well
    assert "\x1b[2J" not in drawn(view)


def test_a_string_counter_and_a_number_as_last_error_show_what_is_valid() -> None:
    view = UnitView(bad_messages=1)
    view.take("status", messages.pack({"v": 1, "health": "degraded", "last_error": 7,
                                       "counters": {"samples_used": 1200, "seq_gaps": "3", "crc_errors": 2}}))
    view.take("attitude", messages.pack({"v": 1, "t": 12.0, "phase": "[/]fine", "q": [1, 0, 0, 0], "pitch_deg": 1.5,
                                         "roll_deg": -0.25, "heading_deg": 90.0, "heading_sigma_deg": 0.5,
                                         "level_sigma_deg": 0.01, "converged": "yes"}))
    shown = cells(view)
    assert shown["loop p99 / max (ms)"] == "- / -"   # a status without the loop's figures
    assert shown["health"] == "degraded" and shown["last error"] == "?" and shown["frames"] == "1200"
    assert shown["drops and faults"] == "≥3"        # crc_errors and the bad message; seq_gaps unreadable
    assert shown["phase"] == "[/]fine" and shown["converged"] == "?" and shown["heading (°)"] == "90.0000"
    drawn(view)


def test_the_loop_figures_show_what_is_a_number() -> None:
    view = UnitView()
    view.take("status", messages.pack({"v": 1, "health": "ok", "counters": {},
                                       "loop": {"reads": 200, "p99_ms": 0.5, "max_ms": 1.25}}))
    assert cells(view)["loop p99 / max (ms)"] == "0.50 / 1.25"
    view.take("status", messages.pack({"v": 1, "health": "ok", "counters": {},
                                       "loop": {"p99_ms": "x", "max_ms": None}}))
    assert cells(view)["loop p99 / max (ms)"] == "? / -"
