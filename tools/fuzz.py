"""Hostile input, measured: what random and absurd input does to every input class of the service.

Each class is fed long random runs and every outcome is counted (:class:`Tally`): accepted, dropped or counted by
the service's own counters, refused with the error type its interface documents, or *escaped*: any other exception
(or, for the sample stream, a record with a non-finite number, or records that stop after the faults). An escape
is a bug; :func:`fault_table` shows them, and ``sinsalign fuzz`` exits 1 on any.

1. serial bytes (:func:`fuzz_serial`): noise, valid IMU and aiding frames with bit flips, truncations, planted sync
   words, into the frame decoder and the payload decoders;
2. Zenoh msgpack messages (:func:`fuzz_messages`): noise, mutated messages, and well-formed messages of every kind
   holding absurd values (float limits, huge integers, a latitude of 95°, a quaternion of norm 7, strings where
   numbers go), into every message decoder;
3. the sample gate and the pipeline (:func:`fuzz_samples`): the daemon's sans-I/O ingest fed simulated IMU streams
   with samples replaced by absurd ones (float limits, subnormals, −0, increments at the range's edge, time stamps
   jumping up to 1e12 s either way, repeats, drops, status and saturation flags);
4. aiding epochs (:func:`fuzz_aiding`): random and absurd values through the msgpack and the serial aiding
   decoders;
5. the replay path (:func:`fuzz_replay`): IMU logs and aiding logs with absurd comment values and cells, cut and
   overlong lines, restart marks and garbage at any depth, replayed as ``sinsalign replay`` does;
6. the configuration (:func:`fuzz_config`): random mappings into ``config_from_mapping`` and random TOML text
   through the loader behind ``--config``.
7. vendor IMU frames (:func:`fuzz_vendor_frames`): each vendor format's valid frames with bit flips, truncations
   and planted first bytes, into its decoder, counter clock and axes as the daemon runs them.

Classes 1, 2, 4 and 7 are sized in inputs, 3, 5 and 6 in generated values (numbers and texts); generation is numpy's
wherever the interface takes arrays or text, so the run's time goes into the code under test.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import reprlib
import shutil
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import msgpack
import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from sinsalign.protocol import messages
from sinsalign.protocol.aiding_log import KINDS as AIDING_LOG_KINDS
from sinsalign.protocol.aiding_log import LEVER_KEYS
from sinsalign.protocol.formats import IMU_FORMATS
from sinsalign.protocol.imu_log import IMU_COLUMNS, RESTART_MARKER, LogFormatError, imu_limits
from sinsalign.protocol.results import ResultRecord
from sinsalign.protocol.serial_frame import (
    AIDING_KIND_CODES,
    AIDING_VALUES,
    MSG_AIDING,
    MSG_IMU,
    SYNC,
    AidingPayloadError,
    Frame,
    FrameDecoder,
    decode_aiding,
    decode_imu,
    encode_aiding,
    encode_imu,
)
from sinsalign.service.config import Config, ConfigError, config_from_mapping, load_config, tables, value_fields
from sinsalign.service.ingest import Ingest
from sinsalign.service.sample_gate import gate_for
from sinsalign.service.serial_formats import serial_format_for
from sinsalign.tools.replay import replay
from sinsalign.tools.sim.files import log_keys
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import daemon_sections, seed_run
from sinsalign.tools.virtual_imu import VENDOR_ENCODERS

Advance = Callable[[int], None]
"""Told how far a run got (inputs or values since the last call): the progress bar."""

MAX_MESSAGE_CHARS = 300
"""A documented refusal is one line of at most this many characters (a file's name, line and column, the value
quoted short); a longer or multi-line one counts as escaped."""
SHOWN_INPUT_CHARS = 1000
"""The most characters of an input an escape's description quotes."""


PROGRESS_STEP = 1024
"""Inputs between two calls of a class's :data:`Advance` (fewer calls than inputs: the bar costs time too)."""


def _ignore(_: int) -> None:
    """The default :data:`Advance`: no progress shown."""


# --- the tally ----------------------------------------------------------------------------------------------------


@dataclass(slots=True)
class Tally:
    """What one input class did with its hostile inputs: every attempt is accepted, refused with ``refusal`` (the
    documented error types) or escaped; ``counters`` are the service's own counts of what it dropped or flagged."""

    name: str
    unit: str
    """What one of ``values`` is (bytes, numbers)."""
    refusal: tuple[type[BaseException], ...]
    inputs: int = 0
    values: int = 0
    accepted: int = 0
    refusals: Counter[str] = field(default_factory=Counter)
    """Refusals by the error type raised (the documented ones, or subclasses of them)."""
    escaped: int = 0
    counters: Counter[str] = field(default_factory=Counter)
    seconds: float = 0.0
    first_escape: str | None = None
    """The first escaped input, described, and its traceback: what to reproduce it from."""

    def escape(self, what: Callable[[], str], exc: BaseException | None = None) -> None:
        """Count an escape; keep the first one's input (``what()``, asked for the first only: it may copy files)
        and traceback."""
        self.escaped += 1
        if self.first_escape is None:
            trace = "".join(traceback.format_exception(exc)) if exc is not None else "(no exception)\n"
            self.first_escape = f"{self.name}: {_short(what())}\n{trace}"

    def attempt(self, call: Callable[[], Any], what: Callable[[], str], one_line: bool = False) -> Any:
        """``call()`` counted: its result if accepted, else None (refused, or escaped: an exception other than the
        documented ``refusal``, or with ``one_line`` a refusal whose message is not one short line). ``what``
        describes the input, only when it escapes."""
        try:
            result = call()
        except self.refusal as exc:
            text = str(exc)
            if one_line and ("\n" in text or len(text) > MAX_MESSAGE_CHARS):
                self.escape(lambda: f"refusal not one short line ({len(text)} characters) on {what()}", exc)
            else:
                self.refusals[type(exc).__name__] += 1
            return None
        except Exception as exc:   # the point of the run: anything else escaped
            self.escape(what, exc)
            return None
        self.accepted += 1
        return result

    def guarded(self, call: Callable[[], Any], what: Callable[[], str]) -> tuple[bool, Any]:
        """``call()`` where nothing is refused: (True, its result), or (False, None) with the exception counted as
        escaped."""
        try:
            return True, call()
        except Exception as exc:   # the point of the run: anything escaped
            self.escape(what, exc)
            return False, None

    @property
    def refused(self) -> int:
        return sum(self.refusals.values())

    def count(self, counters: dict[str, int]) -> None:
        """Add the service's counters of one input (or one decoder's life) to the class's."""
        self.counters.update(counters)


def _fault_counters(counters: dict[str, int], named: Sequence[str] = ()) -> dict[str, int]:
    """The counters that count drops or faults (``messages.faults``), and the ``named`` ones even at zero."""
    return {**dict.fromkeys(named, 0), **{k: counters[k] for k in named}, **messages.faults(counters)}


SHORT_REPR = reprlib.Repr()
"""How an escape's description quotes a Python input: cut short, however deep or long it is."""
SHORT_REPR.maxlevel, SHORT_REPR.maxstring, SHORT_REPR.maxother, SHORT_REPR.maxlong = 4, 60, 60, 60


def _short(text: str) -> str:
    return text if len(text) <= SHOWN_INPUT_CHARS else text[:SHOWN_INPUT_CHARS] + "…"


@contextlib.contextmanager
def _timed(tally: Tally) -> Iterator[Tally]:
    """Time the run into ``tally.seconds``."""
    start = time.perf_counter()
    try:
        yield tally
    finally:
        tally.seconds += time.perf_counter() - start


# --- hostile values -----------------------------------------------------------------------------------------------

FLOAT_MAX = float(np.finfo(float).max)
SUBNORMAL_MIN = 5e-324
EXTREME_FLOATS = np.array([FLOAT_MAX, -FLOAT_MAX, 1e308, -1e308, 1e300, -1e300, 1e30, -1e30, SUBNORMAL_MIN,
                           -SUBNORMAL_MIN, 2.2250738585072014e-308, -0.0, 0.0, 1e-300])
"""Finite float64 values at and near the limits: the largest, the smallest subnormal and normal, both zeros."""
PHYSICAL_ABSURD = np.array([95.0, -90.0, 90.0, 180.5, -180.0001, 7.0, 2.0, 5e3, -12001.0, 1.0001e5, 1e7])
"""Numbers a field can hold but a sensor or a place cannot (a latitude of 95°, a quaternion component of 7)."""
NON_FINITE = np.array([np.nan, np.inf, -np.inf])


def any_magnitudes(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` finite float64 values of random sign and binary exponent from the smallest subnormal to near the
    largest, every scale equally likely: what a corrupt or hostile sender can put in a float."""
    mantissa = rng.uniform(0.5, 1.0, n)
    return rng.choice((-1.0, 1.0), n) * np.ldexp(mantissa, rng.integers(-1074, 1025, n))


def absurd_floats(rng: np.random.Generator, n: int, non_finite: bool = False) -> np.ndarray:
    """``n`` absurd numbers: the extremes, any scale, physically impossible ones; NaN and ±inf with
    ``non_finite``."""
    palette = np.concatenate((EXTREME_FLOATS, PHYSICAL_ABSURD, NON_FINITE if non_finite else []))
    out = any_magnitudes(rng, n)
    pick = rng.random(n) < 0.6
    out[pick] = palette[rng.integers(len(palette), size=int(pick.sum()))]
    return out


HOSTILE_OBJECTS: tuple[object, ...] = (
    FLOAT_MAX, -FLOAT_MAX, 1e308, SUBNORMAL_MIN, -0.0, math.nan, math.inf, -math.inf, 95.0, 7.0,
    2**64 - 1, -(2**63), 2**63, 0, -1, True, False, None, "", "1.0", "nan", "x" * 1000, "é ☃ \u200b",
    [], [1.0] * 100, [[[[1.0]]]], {}, {"v": 1}, b"\x00\xff", [math.nan, 0.0, 0.0],
)
"""Values of any type a msgpack map may hold in place of a number or a list (each packable)."""


POOL_BLOCK = 8192


class Pool:
    """Random numbers drawn from numpy in blocks and handed out one at a time: where an input is built of Python
    objects value by value (a message, a configuration), each costs a step through a list, not a generator call."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._uniform = self._blocks(rng.random)
        self._absurd = self._blocks(partial(absurd_floats, rng, non_finite=True))

    @staticmethod
    def _blocks(draw: Callable[[int], np.ndarray]) -> Iterator[float]:
        while True:
            yield from draw(POOL_BLOCK).tolist()

    def random(self) -> float:
        """U(0, 1)."""
        return next(self._uniform)

    def below(self, n: int) -> int:
        """An integer in 0 .. n − 1."""
        return int(next(self._uniform) * n)

    def absurd(self) -> float:
        """One of :func:`absurd_floats` (NaN and ±inf among them)."""
        return next(self._absurd)


def hostile_object(pool: Pool) -> object:
    """One of :data:`HOSTILE_OBJECTS` (a list or map copied: a message changed further must not change the
    palette), or an absurd float."""
    k = pool.below(len(HOSTILE_OBJECTS) + 4)
    if k >= len(HOSTILE_OBJECTS):
        return pool.absurd()
    value = HOSTILE_OBJECTS[k]
    return list(value) if isinstance(value, list) else dict(value) if isinstance(value, dict) else value


def count_values(value: object) -> int:
    """The numbers and texts in ``value`` (nested lists and maps counted through, their keys too; a
    :class:`Nested` list as one)."""
    if isinstance(value, Nested):
        return 1
    if isinstance(value, dict):
        return sum(1 + count_values(v) for v in value.values())
    if isinstance(value, list | tuple):
        return sum(count_values(v) for v in value)
    return 1


# --- 1. serial bytes ----------------------------------------------------------------------------------------------


def _pieces(rng: np.random.Generator, valid: list[bytes], n: int, sync: bytes = SYNC) -> Iterator[bytes]:
    """``n`` pieces of a hostile serial stream: noise, valid frames with bit flips, cut frames, noise with a sync
    word (``sync``, two bytes) planted in it, and valid frames."""
    for _ in range(n):
        kind = rng.integers(5)
        if kind == 0:
            yield rng.bytes(int(rng.integers(0, 120)))
        elif kind == 1:
            frame = bytearray(valid[rng.integers(len(valid))])
            for _ in range(int(rng.integers(1, 4))):
                frame[rng.integers(len(frame))] ^= 1 << int(rng.integers(8))
            yield bytes(frame)
        elif kind == 2:
            frame = valid[rng.integers(len(valid))]
            yield frame[:int(rng.integers(1, len(frame)))]
        elif kind == 3:
            noise = bytearray(rng.bytes(int(rng.integers(2, 80))))
            at = int(rng.integers(0, len(noise) - 1))
            noise[at:at + 2] = sync
            yield bytes(noise)
        else:
            yield valid[rng.integers(len(valid))]


def _decode_frame(frame: Frame) -> object:
    """A decoded frame's payload as the daemon decodes it (others are passed on, counted by the decoder)."""
    if frame.msg_type == MSG_IMU:
        return decode_imu(frame)
    if frame.msg_type == MSG_AIDING:
        return decode_aiding(frame)
    return frame


def _feed_piece(tally: Tally, decoder: FrameDecoder, piece: bytes) -> FrameDecoder:
    """One piece into the decoder and its frames into their payload decoders; the decoder to go on with (a fresh
    one if this one raised: it must never, and its state is lost)."""
    try:
        frames = decoder.feed(piece)
    except Exception as exc:   # the frame decoder itself must never raise
        tally.escape(partial(_hex, "piece", piece), exc)
        tally.count(_fault_counters(decoder.all_counters()))
        return FrameDecoder()
    for frame in frames:
        tally.attempt(partial(_decode_frame, frame), lambda f=frame: f"frame {f!r} in piece {piece.hex()}")
    return decoder


def fuzz_serial(inputs: int = 1_000_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """``inputs`` random pieces into one frame decoder; every frame it finds into its payload decoder (IMU, aiding:
    ``AidingPayloadError`` is the documented refusal). Values: bytes fed."""
    tally = Tally("serial bytes", "bytes", (AidingPayloadError,))
    rng = np.random.default_rng(seed)
    valid = [encode_imu(k, 0.005 * (k + 1), rng.normal(0, 1e-3, 3), rng.normal(0, 0.1, 3)) for k in range(256)]
    valid += [encode_aiding(k, 0.005 * (k + 1), kind, rng.normal(0, 10, n))
              for k in range(32) for kind, n in AIDING_VALUES.items()]
    decoder = FrameDecoder()
    with _timed(tally):
        for k, piece in enumerate(_pieces(rng, valid, inputs), 1):
            tally.inputs += 1
            tally.values += len(piece)
            decoder = _feed_piece(tally, decoder, piece)
            if k % PROGRESS_STEP == 0:
                advance(PROGRESS_STEP)
        tally.count(_fault_counters(decoder.all_counters()))
    advance(inputs % PROGRESS_STEP)
    return tally


# --- 7. vendor IMU frames -----------------------------------------------------------------------------------------


VENDOR_FRAME = {"sync": "A5 5A", "length": 16, "endian": "little", "checksum": "xor8", "checksum_from": 2,
                "fields": ["counter u8", "dtheta_x i16 1e-6", "dtheta_y i16 1e-6", "dtheta_z i16 1e-6",
                           "dv_x i16 1e-4", "dv_y i16 1e-4", "dv_z i16 1e-4", "checksum u8"]}
"""The declared frame the fuzzer feeds (``[imu] format = "frame"``)."""


def vendor_config(name: str) -> Config:
    """The configuration of the vendor format ``name`` the fuzzer feeds."""
    return config_from_mapping({"imu": {"format": name, **({"frame": VENDOR_FRAME} if name == "frame" else {})}})


def fuzz_vendor_frames(inputs: int = 200_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """``inputs`` random pieces, spread over the vendor formats, each into its format's decoder as the daemon runs
    it (counter time stamps on a host clock of its own, axes): valid frames with bit flips, cut frames, noise with
    the frame's first two bytes planted in it. Escaped: an exception, or a sample row that is not finite. Values:
    bytes fed."""
    tally = Tally("vendor IMU frames", "bytes", ())
    rng = np.random.default_rng(seed)
    names = [name for name in IMU_FORMATS if name != "sinsalign"]
    with _timed(tally):
        for j, name in enumerate(names):
            config = vendor_config(name)
            encoder = VENDOR_ENCODERS[name](config.imu)
            valid = [encoder.encode(k, rng.normal(0, 1e-3, 3), rng.normal(0, 0.05, 3), int(rng.integers(2)))
                     for k in range(256)]
            clock = iter(np.cumsum(rng.exponential(2e-3, inputs + 1)))
            serial_format = serial_format_for(config, lambda c=clock: float(next(c)))
            share = inputs // len(names) + (j < inputs % len(names))
            for k, piece in enumerate(_pieces(rng, valid, share, valid[0][:2]), 1):
                tally.inputs += 1
                tally.values += len(piece)
                ok, decoded = tally.guarded(partial(serial_format.feed, piece), partial(_hex, f"{name} piece", piece))
                if not ok:
                    serial_format = serial_format_for(config)
                elif not np.isfinite(decoded.samples).all():
                    tally.escape(partial(_hex, f"{name} piece (a row not finite)", piece))
                else:
                    tally.accepted += len(decoded.samples)
                if k % PROGRESS_STEP == 0:
                    advance(PROGRESS_STEP)
            tally.count(_fault_counters(serial_format.counters()))
            advance(share % PROGRESS_STEP)
    return tally


# --- 2. Zenoh msgpack messages ------------------------------------------------------------------------------------


def _valid_messages() -> dict[str, dict[str, Any]]:
    """One well-formed message of every kind the daemon reads or its clients read: IMU, attitude, status and each
    aiding kind."""
    record = ResultRecord(t=1.0, phase="coarse", q=(1.0, 0.0, 0.0, 0.0), pitch_deg=0.0, roll_deg=0.0,
                          heading_deg=10.0, heading_sigma_deg=1.0, level_sigma_deg=0.1, converged=False, rho=0.1,
                          trace_P=1.0, n_obs=1)
    aiding = {"odo": {"v_b": (1.0, 0.0, 0.0)},
              "gnss": {"lat_deg": (32.0,), "lon_deg": (118.0,), "h_m": (10.0,), "v_enu": (0.0, 50.0, 0.0)},
              "master": {"q": (1.0, 0.0, 0.0, 0.0), "v_enu": (0.0, 50.0, 0.0), "lat_deg": (32.0,),
                         "lon_deg": (118.0,), "h_m": (10.0,)}}
    return {"imu": messages.imu_message(messages.ImuSample(1, 0.005, (1e-5, 0.0, 0.0), (0.0, 0.0, 0.049), 0)),
            "attitude": messages.attitude_message("unit1", record),
            "status": messages.status_message("unit1", 1.0, "ok", "coarse", 1.0, None, {"frames": 1}),
            **{kind: messages.aiding_message(messages.AidingSample(kind, 0, 1.0, values))
               for kind, values in aiding.items()}}


def absurd_message(pool: Pool, message: dict[str, Any]) -> dict[str, Any]:
    """``message`` with 1 to 3 of its values (a field, or one number of a list field) replaced by hostile ones."""
    out = {key: list(value) if isinstance(value, list) else value for key, value in message.items()}
    keys = list(out)
    for _ in range(1 + pool.below(3)):
        key = keys[pool.below(len(keys))]
        if isinstance(out[key], list) and out[key] and pool.random() < 0.7:
            out[key][pool.below(len(out[key]))] = hostile_object(pool)
        else:
            out[key] = hostile_object(pool)
    return out


MESSAGE_DECODERS: tuple[Callable[[bytes, str], object], ...] = (
    lambda data, kind: messages.decode_imu(data),
    lambda data, kind: messages.decode_attitude(data),
    lambda data, kind: messages.decode_status(data),
    lambda data, kind: messages.decode_aiding(kind, data),
)
"""Every msgpack decoder, called with the message and the aiding kind its key would name."""


def _message(pool: Pool, k: int, valid: dict[str, dict[str, Any]], packed: list[bytes]) -> bytes:
    """Message ``k``: random bytes, a valid message with one byte changed, or a well-formed one of absurd values
    (in turn)."""
    style = k % 3
    if style == 0:
        return pool.rng.bytes(pool.below(64))
    if style == 1:
        buffer = bytearray(packed[k % len(packed)])
        buffer[pool.below(len(buffer))] = pool.below(256)
        return bytes(buffer)
    return msgpack.packb(absurd_message(pool, valid[list(valid)[k % len(valid)]]), use_bin_type=True)


def fuzz_messages(inputs: int = 200_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """``inputs`` messages (:func:`_message`), each into every message decoder, an aiding one with the kind of its
    message or another (``MessageError`` is the documented refusal). Values: bytes."""
    tally = Tally(f"Zenoh msgpack messages (each into the {len(MESSAGE_DECODERS)} decoders)", "bytes",
                  (messages.MessageError,))
    pool = Pool(np.random.default_rng(seed))
    valid = _valid_messages()
    names = list(valid)
    packed = [messages.pack(m) for m in valid.values()]
    other_kinds = (*AIDING_KIND_CODES, "x" * 100)
    with _timed(tally):
        for k in range(1, inputs + 1):
            data = _message(pool, k, valid, packed)
            name = names[k % len(names)]
            kind = name if name in AIDING_KIND_CODES else other_kinds[k % len(other_kinds)]
            tally.inputs += 1
            tally.values += len(data)
            for decode in MESSAGE_DECODERS:
                tally.attempt(partial(decode, data, kind), partial(_hex, f"{kind} message", data))
            if k % PROGRESS_STEP == 0:
                advance(PROGRESS_STEP)
    advance(inputs % PROGRESS_STEP)
    return tally


def _hex(what: str, data: bytes) -> str:
    return f"{what} {data.hex()}"


# --- 3. the sample gate and the pipeline --------------------------------------------------------------------------

STREAM_SCENARIO = "seed000-swing"
"""The daemon tests' scenario: a ship's IMU on a swinging base, 200 Hz."""
STREAM_OUTPUT_PERIOD_S = 0.5
STREAM_SAMPLES = (1_000, 6_000)
"""A stream's length in samples (5 to 30 s at 200 Hz)."""
TAIL_SAMPLES = 800
"""The clean samples after a stream's last fault (4 s at 200 Hz): the alignment must publish again in them."""
MAX_DROPPED_RUN = 20
TIME_JUMP_EXPONENTS = (-3.0, 12.0)
"""A time stamp's jump, forward or back, is 10^U(-3, 12) s: from a millisecond to 30000 years."""
SAMPLE_FAULTS = ("value", "all_values", "range_edge", "wild_stamp", "time_step", "repeat", "dropped", "status",
                 "saturated")
"""What a fault does to a sample: one or all six increments absurd, one at the edge of the IMU's range, its time
stamp wild, every time stamp from it on shifted, the sample repeated or a run dropped, its status word set, its
saturation flag set."""


@dataclass(frozen=True, slots=True)
class SimulatedImu:
    """A simulated IMU run: t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s, and the scenario it is from."""

    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    scenario: Any


def imu_rate(name: str) -> float:
    """The sample rate of scenario ``name`` (Hz)."""
    return seed_run(name, 0).rate_hz


def simulated_imu(seconds: float, seed: int) -> SimulatedImu:
    """``seconds`` of the stream scenario as seed ``seed`` runs it."""
    scenario = seed_run(STREAM_SCENARIO, seed, seconds)
    chunks = list(simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, seed))
    return SimulatedImu(np.concatenate([c.t for c in chunks]), np.concatenate([c.dtheta for c in chunks]),
                        np.concatenate([c.dv for c in chunks]), scenario)


def stream_config(scenario: Any) -> Config:
    """The daemon's configuration for ``scenario``'s IMU (site, rate, datasheet) with a 0.5-s output period."""
    return config_from_mapping({**daemon_sections(scenario), "output": {"period_s": STREAM_OUTPUT_PERIOD_S}})


CLOCK_STEP_EXPONENTS = (-3.0, 9.0)
"""A clock set anew jumps by 1 ms to 1e9 s: ten steps stay within the 1e10 s any clock can read."""


def _jumps(rng: np.random.Generator, n: int, exponents: tuple[float, float] = TIME_JUMP_EXPONENTS) -> np.ndarray:
    """``n`` time jumps (s): forward or back, 10**exponents[0] to 10**exponents[1] s, every scale equally likely."""
    return rng.choice((-1.0, 1.0), n) * 10.0 ** rng.uniform(*exponents, n)


@dataclass(frozen=True, slots=True)
class HostileStream:
    """Samples as a decoder hands them over, with the faults planted in them."""

    samples: np.ndarray
    """(N, :data:`~sinsalign.service.sample_gate.SAMPLE_COLUMNS`): t, Δθ, Δv, status, saturated."""
    tail_start: int
    """Index of the first sample after the last fault."""
    faults: list[tuple[int, str]]
    """(index in the original run, fault) of each fault."""


def hostile_stream(rng: np.random.Generator, imu: SimulatedImu, max_dtheta: float, max_dv: float) -> HostileStream:
    """A window of ``imu`` with faults (:data:`SAMPLE_FAULTS`) at random samples before its clean tail; no NaN
    (no decoder hands one over), everything else a sender can put in a finite float."""
    n = int(rng.integers(*STREAM_SAMPLES))
    first = int(rng.integers(0, len(imu.t) - n))
    values = np.hstack((imu.dtheta[first:first + n], imu.dv[first:first + n]))
    at = np.sort(rng.choice(n - TAIL_SAMPLES - MAX_DROPPED_RUN, int(rng.integers(1, max(2, n // 100))),
                            replace=False))
    kind = rng.integers(len(SAMPLE_FAULTS), size=len(at))
    faulted = {name: at[kind == k] for k, name in enumerate(SAMPLE_FAULTS)}
    _plant_value_faults(rng, values, faulted, max_dtheta, max_dv)
    t = _faulted_times(rng, imu.t[first:first + n], faulted)
    status, saturated = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool)
    status[faulted["status"]] = rng.integers(1, 2**32, len(faulted["status"]))
    saturated[faulted["saturated"]] = True
    order = np.repeat(np.arange(n), _copies(rng, n, faulted))
    samples = np.column_stack((t[order], values[order], status[order], saturated[order]))
    return HostileStream(samples, int(np.searchsorted(order, n - TAIL_SAMPLES)),
                         [(first + int(k), SAMPLE_FAULTS[c]) for k, c in zip(at, kind, strict=True)])


def _plant_value_faults(rng: np.random.Generator, values: np.ndarray, faulted: dict[str, np.ndarray],
                        max_dtheta: float, max_dv: float) -> None:
    """The increment faults in place (``faulted``: the samples of each fault): one (``value``) or all six
    (``all_values``) absurd, or one at U(0.5, 1) of the IMU's range (``range_edge``: the gate lets it through to
    the estimator)."""
    one = faulted["value"]
    values[one, rng.integers(6, size=len(one))] = absurd_floats(rng, len(one))
    every = faulted["all_values"]
    values[every] = absurd_floats(rng, 6 * len(every)).reshape(-1, 6)
    edge = faulted["range_edge"]
    axis = rng.integers(6, size=len(edge))
    limit = np.where(axis < 3, max_dtheta, max_dv)
    values[edge, axis] = rng.choice((-1.0, 1.0), len(edge)) * limit * rng.uniform(0.5, 1.0, len(edge))


def _faulted_times(rng: np.random.Generator, t: np.ndarray, faulted: dict[str, np.ndarray]) -> np.ndarray:
    """The time stamps (s) with every one from a ``time_step`` on shifted (a clock set anew: it still reads a time,
    within 1e9 s), and each ``wild_stamp`` alone (up to 1e12 s: beyond any clock, dropped)."""
    shifts = np.zeros(len(t))
    shifts[faulted["time_step"]] = _jumps(rng, len(faulted["time_step"]), CLOCK_STEP_EXPONENTS)
    t = t + np.cumsum(shifts)
    t[faulted["wild_stamp"]] += _jumps(rng, len(faulted["wild_stamp"]))
    return t


def _copies(rng: np.random.Generator, n: int, faulted: dict[str, np.ndarray]) -> np.ndarray:
    """How many times each of ``n`` samples is handed over: 2 to 9 for a ``repeat``, 0 for a run of up to
    :data:`MAX_DROPPED_RUN` from a ``dropped``, else 1."""
    copies = np.ones(n, dtype=np.int64)
    copies[faulted["repeat"]] = rng.integers(2, 10, len(faulted["repeat"]))
    for k in faulted["dropped"].tolist():
        copies[k:k + int(rng.integers(1, MAX_DROPPED_RUN + 1))] = 0
    return copies


STREAM_COUNTERS = ("implausible", "clock_resets", "restarts", "estimator_restarts")
"""The ingest's counters the table names even at zero: what hostile samples cost."""


def _feed(ingest: Ingest, rng: np.random.Generator, samples: Sequence) -> list[ResultRecord]:
    """``samples`` into ``ingest`` in random pieces of 1 to 200 (as serial reads hand them over)."""
    records: list[ResultRecord] = []
    at = 0
    while at < len(samples):
        size = int(rng.integers(1, 201))
        records += ingest.feed_samples(samples[at:at + size])
        at += size
    return records


def finite_record(record: ResultRecord) -> bool:
    """Whether a record the stream gave holds finite numbers only (:attr:`ResultRecord.finite`): the check of the
    sample class, kept apart from the one the alignment makes of its own steps."""
    return record.finite


def _check_stream(tally: Tally, stream: HostileStream, before: list[ResultRecord], tail: list[ResultRecord],
                  what: Callable[[], str]) -> None:
    """Every record finite, and the clean tail's records reach to within two output periods of its end."""
    bad = next((r for r in (*before, *tail) if not finite_record(r)), None)
    t_end = stream.samples[-1][0]
    if bad is not None:
        tally.escape(lambda: f"non-finite record {bad!r} in {what()}")
    elif not tail or tail[-1].t < t_end - 2 * STREAM_OUTPUT_PERIOD_S:
        tally.escape(lambda: f"no record near the end (t = {t_end!r} s) after the last fault (last: "
                     f"{tail[-1].t if tail else None!r}) in {what()}")


def _run_stream(tally: Tally, rng: np.random.Generator, config: Config, stream: HostileStream,
                what: Callable[[], str]) -> None:
    """One hostile stream into a fresh ingest: the samples up to its last fault, then its clean tail; checked
    (:func:`_check_stream`) and counted."""
    ingest = Ingest(config, lambda text: None)
    fed, before = tally.guarded(partial(_feed, ingest, rng, stream.samples[:stream.tail_start]), what)
    if fed:
        fed, tail = tally.guarded(partial(_feed, ingest, rng, stream.samples[stream.tail_start:]), what)
        if fed:
            _check_stream(tally, stream, before, tail, what)
    counters = ingest.all_counters()
    tally.accepted += counters["samples_used"] - counters["samples_bridged"]
    tally.count(_fault_counters(counters, STREAM_COUNTERS))


def fuzz_samples(values: int = 400_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """Hostile streams (:func:`hostile_stream`) into the daemon's ingest, until ``values`` numbers (t, Δθ, Δv: 7
    per sample) have gone in. Nothing is refused: a bad sample is dropped or bridged, a bad stretch restarts the
    alignment, each counted; accepted: the samples the alignment took; escaped: an exception, a non-finite record,
    or no record after the last fault."""
    tally = Tally("sample gate and pipeline (`Ingest`)", "numbers", ())
    rng = np.random.default_rng(seed)
    imu = simulated_imu(STREAM_SAMPLES[1] / imu_rate(STREAM_SCENARIO) + 20.0, seed)
    config = stream_config(imu.scenario)
    gate = gate_for(config)
    with _timed(tally):
        while tally.values < values:
            stream = hostile_stream(rng, imu, gate.max_dtheta_rad, gate.max_dv_mps)
            _run_stream(tally, rng, config, stream, partial(_stream_text, tally.inputs, seed, stream))
            tally.inputs += 1
            tally.values += 7 * len(stream.samples)
            advance(7 * len(stream.samples))
    return tally


def _stream_text(index: int, seed: int, stream: HostileStream) -> str:
    return f"stream {index} of seed {seed}, faults (sample, kind): {stream.faults[:20]}"


# --- 4. aiding epochs ---------------------------------------------------------------------------------------------


def plausible_epochs(rng: np.random.Generator, kind: str, n: int) -> np.ndarray:
    """``n`` epochs (rows of the kind's values in wire order) a real source of ``kind`` could send."""
    lat = rng.uniform(-89.0, 89.0, n)
    lon = rng.uniform(-180.0, 180.0, n)
    height = rng.uniform(-100.0, 1e4, n)
    speed = rng.normal(0.0, 30.0, (n, 3))
    if kind == "odo":
        return speed
    if kind == "gnss":
        return np.column_stack((lat, lon, height, speed))
    q = rng.normal(size=(n, 4))
    return np.column_stack((q / np.linalg.norm(q, axis=1, keepdims=True), speed, lat, lon, height))


def hostile_epochs(rng: np.random.Generator, kind: str, n: int) -> np.ndarray:
    """Plausible epochs with a random share of their values replaced by absurd ones (NaN and ±inf included)."""
    rows = plausible_epochs(rng, kind, n)
    bad = rng.random(rows.shape) < rng.uniform(0.0, 0.5, (n, 1))
    rows[bad] = absurd_floats(rng, int(bad.sum()), non_finite=True)
    return rows


def _aiding_payload(pool: Pool, kind: str, row: np.ndarray) -> bytes:
    """The serial aiding payload of ``row``: its kind code (now and then another byte) and float64 values, now and
    then cut or lengthened."""
    code = AIDING_KIND_CODES[kind] if pool.random() < 0.9 else pool.below(256)
    payload = bytes([code]) + row.astype("<f8").tobytes()
    if pool.random() < 0.05:
        payload = payload[:pool.below(len(payload))] if pool.random() < 0.5 else payload + pool.rng.bytes(8)
    return payload


def _aiding_message(pool: Pool, kind: str, t: float, row: np.ndarray) -> bytes:
    """The msgpack aiding message of ``row``, now and then a field replaced by a hostile object."""
    values, at = {}, 0
    for name, count in messages.AIDING_FIELDS[kind].items():
        values[name] = row[at] if count == 1 else row[at:at + count].tolist()
        at += count
    message: dict[str, Any] = {"v": messages.VERSION, "seq": pool.below(2**32), "t": t,
                               **{k: float(v) if isinstance(v, float | np.floating) else v for k, v in values.items()}}
    if pool.random() < 0.2:
        message = absurd_message(pool, message)
    return msgpack.packb(message, use_bin_type=True)


def _try_epoch(tally: Tally, pool: Pool, kind: str, t: float, row: np.ndarray) -> None:
    """One epoch through both aiding decoders."""
    data = _aiding_message(pool, kind, t, row)
    frame = Frame(MSG_AIDING, pool.below(2**16), pool.below(2**63), _aiding_payload(pool, kind, row))
    tally.attempt(partial(messages.decode_aiding, kind, data), partial(_hex, f"{kind} message", data))
    tally.attempt(partial(decode_aiding, frame), partial(repr, frame))
    tally.inputs += 1
    tally.values += 1 + len(row)


def fuzz_aiding(inputs: int = 200_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """``inputs`` aiding epochs of every kind (:func:`hostile_epochs`, a tenth with an absurd time), each through
    the Zenoh decoder (``decode_aiding(kind, msgpack)``) and the serial one (``decode_aiding(frame)``);
    ``MessageError`` (``AidingPayloadError`` on serial) is the documented refusal. Values: the epoch's numbers (t
    and the kind's values)."""
    tally = Tally("aiding epochs (Zenoh and serial decoders)", "numbers", (messages.MessageError,))
    rng = np.random.default_rng(seed)
    kinds = list(AIDING_KIND_CODES)
    pool = Pool(rng)
    with _timed(tally):
        while tally.inputs < inputs:
            kind = kinds[tally.inputs // PROGRESS_STEP % len(kinds)]
            n = min(PROGRESS_STEP, inputs - tally.inputs)
            rows = hostile_epochs(rng, kind, n)
            times = np.where(rng.random(n) < 0.1, absurd_floats(rng, n, non_finite=True), rng.uniform(0, 1e5, n))
            for row, t in zip(rows, times.tolist(), strict=True):
                _try_epoch(tally, pool, kind, t, row)
            advance(n)
    return tally


# --- 5. the replay path -------------------------------------------------------------------------------------------

LOG_ROWS = (50, 2_000)
"""An IMU log's rows (log-uniform)."""
DEEP_LOG_ROWS = (20_500, 25_000)
"""The rows of one log in fifty: past the reader's first chunk of 20000 rows, so a fault may lie deep in a file whose
first part the alignment has already taken."""
DEEP_LOG_SHARE = 0.02
AIDED_SHARE = 0.3
"""The replays with an aiding log (of a random kind) beside the IMU log."""
LONG_LINE_CHARS = (4_000, 9_000)
"""An overlong line's length: on both sides of the reader's 4096-character limit, short of megabytes (speed)."""
CELL_GARBAGE = ("nan", "inf", "-inf", "1e999", "-1e999", "", " ", "abc", "1.2.3", "0x1p3", "1_0", "--1", "1e", "+",
                "١٢", "\x00", "1,5", "9" * 400, "-0", "5e-324", "1e-400", "NaN", "Infinity", "true")
"""Cells a log may hold where a number goes."""
CELL_FAULTS = ("absurd_cell", "garbage_cell", "in_limits", "time_back")
"""Faults of one cell: an absurd number, no number, a number within the log's limits but no sensor's, a time
stamp 0 to 10 s back."""
LINE_FAULTS = (*CELL_FAULTS, "cut_line", "long_line", "garbage_line", "restart_mark", "extra_cells",
               "missing_cell")
"""Faults of a data line: one of its cells, or the line cut, overlong, replaced by random bytes, after a restart
mark, with cells too many or one too few."""
COMMENT_GARBAGE = ("1e308", "-1e308", "5e-324", "-0", "nan", "inf", "", "abc", "95", "-90", "1e-300", "0x10",
                   "1_000", "9" * 4000, "1e5", "10001", "0.5", "1 2 3")
"""Values of a log's comment keys: beyond their ranges, at their edges, not numbers."""


def _logarithmic(rng: np.random.Generator, low: int, high: int) -> int:
    return round(math.exp(rng.uniform(math.log(low), math.log(high))))


def _comment_lines(rng: np.random.Generator, keys: dict[str, object]) -> list[str]:
    """``# key=value`` lines of ``keys``, a random share of their values absurd (:data:`COMMENT_GARBAGE` or an
    absurd float), now and then a key left out or an extra one stated."""
    share = rng.uniform(0.0, 0.3) if rng.random() < 0.3 else 0.0
    lines = []
    for key, value in keys.items():
        if rng.random() < 0.02:
            continue
        if rng.random() < share:
            value = (COMMENT_GARBAGE[int(rng.integers(len(COMMENT_GARBAGE)))] if rng.random() < 0.5
                     else repr(float(absurd_floats(rng, 1, non_finite=True)[0])))
        lines.append(f"# {key}={value}")
    if rng.random() < 0.05:
        lines += [f"# key{k}=1" for k in range(int(rng.integers(1, 1200)))]
    return lines


def _cells(rows: np.ndarray) -> np.ndarray:
    """Rows as text cells with round-trip precision (17 significant digits), as the log writer writes them."""
    return np.char.mod("%.17g", rows)


def _cell(rng: np.random.Generator, fault: str, cell: str, limit: float) -> str:
    """The text of one cell faulted by ``fault`` (:data:`CELL_FAULTS`), the column's limit being ``limit``."""
    if fault == "absurd_cell":
        return repr(float(absurd_floats(rng, 1)[0]))
    if fault == "garbage_cell":
        return CELL_GARBAGE[int(rng.integers(len(CELL_GARBAGE)))]
    if fault == "in_limits":
        return repr(float(rng.choice((-1.0, 1.0)) * limit * rng.uniform(0.5, 1.0)))
    return repr(float(cell) - float(rng.uniform(0.0, 10.0)))


def _line_fault(rng: np.random.Generator, cells: np.ndarray, line: str, limits: np.ndarray) -> list[str]:
    """The line(s) that replace data line ``line`` (its ``cells``) for one fault of :data:`LINE_FAULTS`."""
    fault = LINE_FAULTS[int(rng.integers(len(LINE_FAULTS)))]
    if fault in CELL_FAULTS:
        column = 0 if fault == "time_back" else int(rng.integers(len(cells)))
        cells = cells.copy()
        cells[column] = _cell(rng, fault, str(cells[column]), float(limits[column]))
        return [",".join(cells)]
    if fault == "cut_line":
        return [line[:int(rng.integers(len(line)))]]
    if fault == "long_line":
        pad = int(rng.integers(*LONG_LINE_CHARS))
        return [line + (" " * pad if rng.random() < 0.5 else "," + "7" * pad)]
    if fault == "garbage_line":
        return [rng.bytes(int(rng.integers(1, 200))).decode("utf-8", "surrogateescape").replace("\n", "")]
    if fault == "restart_mark":
        return [f"{RESTART_MARKER} fuzz", line]
    if fault == "extra_cells":
        return [line + "," + ",".join(cells[:int(rng.integers(1, 4))])]
    return [",".join(cells[:-1])]


def hostile_log_text(rng: np.random.Generator, keys: dict[str, object], columns: tuple[str, ...], rows: np.ndarray,
                     limits: np.ndarray) -> str:
    """A log (comment keys, header row, data rows) with faults on a random few lines (two logs in five have none),
    the header row now and then wrong and the file now and then cut inside its last line."""
    cells = _cells(rows)
    lines = [",".join(r) for r in cells.tolist()]
    n_faults = 0 if rng.random() < 0.4 else int(rng.integers(1, 6))
    for k in sorted(rng.choice(len(lines), min(n_faults, len(lines)), replace=False).tolist(), reverse=True):
        lines[k:k + 1] = _line_fault(rng, cells[k], lines[k], limits)
    header = ",".join(columns) if rng.random() < 0.97 else ",".join(reversed(columns))
    text = "\n".join((*_comment_lines(rng, keys), header, *lines)) + "\n"
    return text[:-int(rng.integers(1, 6))] if rng.random() < 0.05 else text


def raw_bytes(text: str) -> bytes:
    """``text`` as the file's bytes: its garbage (random bytes decoded with ``surrogateescape``) as they were."""
    return text.encode("utf-8", "surrogateescape")


def _aiding_keys(rng: np.random.Generator, kind: str) -> dict[str, object]:
    """An aiding log's optional keys: each of its noise figures and lever arm axes now and then stated."""
    spec = AIDING_LOG_KINDS[kind]
    names = (*spec.std_keys, *(LEVER_KEYS if spec.has_lever else ()))
    return {name: f"{rng.uniform(0.01, 1.0):.6g}" for name in names if rng.random() < 0.3}


def _aiding_rows(rng: np.random.Generator, kind: str, t_end: float) -> np.ndarray:
    """10-Hz epochs of ``kind`` over 0..``t_end`` s: plausible values, in the log's column order."""
    t = np.arange(0.1, t_end, 0.1)
    return np.column_stack((t, plausible_epochs(rng, kind, len(t))))


@dataclass(frozen=True, slots=True)
class ReplayInput:
    """An IMU log (and an aiding log, kind → path) written for one replay, and how many values they hold."""

    imu: Path
    aids: dict[str, str]
    values: int


def write_replay_input(rng: np.random.Generator, imu: SimulatedImu, seed: int, folder: Path) -> ReplayInput:
    """A hostile IMU log of a window of ``imu`` and, for three in ten, an aiding log of a random kind."""
    deep = rng.random() < DEEP_LOG_SHARE
    n = min(int(rng.integers(*DEEP_LOG_ROWS)) if deep else _logarithmic(rng, *LOG_ROWS), len(imu.t))
    first = int(rng.integers(0, len(imu.t) - n + 1))
    rows = np.column_stack((imu.t[first:first + n], imu.dtheta[first:first + n], imu.dv[first:first + n]))
    keys = log_keys(imu.scenario, seed)
    limit = imu_limits(imu.scenario.rate_hz)
    limits = np.array([limit.cells[c].high for c in IMU_COLUMNS])
    path = folder / "imu.csv"
    path.write_bytes(raw_bytes(hostile_log_text(rng, keys, IMU_COLUMNS, rows, limits)))
    if rng.random() >= AIDED_SHARE:
        return ReplayInput(path, {}, rows.size + len(keys))
    kind = list(AIDING_LOG_KINDS)[int(rng.integers(len(AIDING_LOG_KINDS)))]
    aid_path, aid_values = write_aiding_log(rng, kind, float(rows[-1, 0]), folder)
    return ReplayInput(path, {kind: str(aid_path)}, rows.size + len(keys) + aid_values)


def write_aiding_log(rng: np.random.Generator, kind: str, t_end: float, folder: Path) -> tuple[Path, int]:
    """A hostile aiding log of ``kind`` over 0..``t_end`` s in ``folder``: its path and how many values it holds.
    A cell fault within limits takes the kind's limit of its column, 1000 where a vector's norm is what is held."""
    spec = AIDING_LOG_KINDS[kind]
    rows = _aiding_rows(rng, kind, t_end)
    keys = _aiding_keys(rng, kind)
    limits = np.array([spec.limits.cells[c].high if c in spec.limits.cells else 1e3 for c in spec.columns])
    path = folder / f"{kind}.csv"
    path.write_bytes(raw_bytes(hostile_log_text(rng, keys, spec.columns, rows, limits)))
    return path, rows.size + len(keys)


REPLAY_NOTICE = "replay: alignment failed"
"""How the replay tells of a failed estimator step it restarted from (on stderr)."""


def kept_copy(paths: Sequence[Path | str]) -> str:
    """Copies of an escaped input's files in a new folder that stays (the temporary ones do not): its name."""
    folder = Path(tempfile.mkdtemp(prefix="sinsalign-fuzz-escape-"))
    for path in paths:
        shutil.copy(path, folder / Path(path).name)
    return str(folder)


def _replay_once(tally: Tally, config: Config, written: ReplayInput, out: Path, what: Callable[[], str]) -> None:
    """One replay of ``written``; the estimator restarts it tells of, and its sample gate's counters, counted."""
    notices = io.StringIO()
    with contextlib.redirect_stderr(notices):
        summary = tally.attempt(partial(replay, written.imu, out, config, progress=False, aids=written.aids), what,
                                one_line=True)
    tally.counters["estimator_restarts"] += notices.getvalue().count(REPLAY_NOTICE)
    for name, value in (summary.gate.items() if summary is not None else ()):
        tally.counters[name] += value
    tally.inputs += 1
    tally.values += written.values


def _replay_text(index: int, seed: int, written: ReplayInput, config: Config) -> str:
    """Where an escaped replay's logs and configuration (config.json) are kept."""
    folder = kept_copy([written.imu, *written.aids.values()])
    (Path(folder) / "config.json").write_text(json.dumps(config.as_dict()))
    return f"replay input {index} of seed {seed}: its logs and config.json kept in {folder}"


CONFIGURED_SHARE = 1 / 3
"""The replays that run on a random configuration the loader accepted (every key in its range, however extreme);
the others on the defaults."""
CONFIG_TRIES = 200


def accepted_config(pool: Pool, sections: dict[str, list[Key]]) -> Config:
    """A random configuration ``config_from_mapping`` accepts (:func:`random_mapping` until one is; the defaults if
    none of :data:`CONFIG_TRIES` is)."""
    for _ in range(CONFIG_TRIES):
        with contextlib.suppress(ConfigError):
            return config_from_mapping(random_mapping(pool, sections))
    return Config()


def fuzz_replay(values: int = 400_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """Hostile IMU and aiding logs (:func:`write_replay_input`) replayed as ``sinsalign replay`` does, a third on a
    random accepted configuration, until ``values`` cells and comment keys have been written; one line of
    ``LogFormatError``, ``ConfigError`` or ``OSError`` is the documented refusal. Counted: the estimator restarts
    the replay told of."""
    tally = Tally("replay path (IMU and aiding logs, `replay`)", "cells and keys", (LogFormatError, ConfigError,
                                                                                     OSError))
    rng = np.random.default_rng(seed)
    pool = Pool(rng)
    sections = _sections()
    imu = simulated_imu(DEEP_LOG_ROWS[1] / imu_rate(STREAM_SCENARIO) + 1.0, seed)
    with tempfile.TemporaryDirectory(prefix="sinsalign-fuzz-") as tmp, _timed(tally):
        folder = Path(tmp)
        while tally.values < values:
            written = write_replay_input(rng, imu, seed, folder)
            config = accepted_config(pool, sections) if pool.random() < CONFIGURED_SHARE else Config()
            _replay_once(tally, config, written, folder / "results.jsonl",
                         partial(_replay_text, tally.inputs, seed, written, config))
            advance(written.values)
    return tally


# --- 6. the configuration -----------------------------------------------------------------------------------------

TEXTS = ("auto", "opreq", "gls", "centred", "vif", "pif", "sigma", "time", "restart", "report", "peer", "client",
         "odo", "gnss", "master", "", "x" * 5000, "a/b", "**", "$", "é", "tcp/127.0.0.1:7447", "\x00")
"""Texts for a text key: the names some keys take, and names no key takes."""
MAX_LIST = 200
"""The longest list drawn (the longest any key takes is 100)."""


@dataclass(frozen=True, slots=True)
class Key:
    """A configuration key: its name, default, field metadata (range, lengths, characters), and whether it holds
    texts."""

    name: str
    default: object
    meta: dict
    texts: bool


def _sections() -> dict[str, list[Key]]:
    """Every configuration key, by table (``aiding.odo`` for a sub-table)."""
    return {name: [Key(f.name, getattr(table, f.name), dict(f.metadata), "str" in str(f.type))
                   for f in value_fields(table)] for name, table in tables(Config())}


class Nested(list):
    """A list nested ``depth`` deep (the innermost empty), built without recursion and written as TOML
    without it."""

    def __init__(self, depth: int) -> None:
        inner: list = []
        for _ in range(depth - 1):
            inner = [inner]
        super().__init__([inner])
        self.depth = depth


def _huge_int(pool: Pool) -> int:
    """An integer of 2 to 5000 digits, either sign: past float64 and past Python's 4300-digit text limit."""
    return 10 ** (1 + pool.below(4999)) * (1 if pool.random() < 0.5 else -1)


def _key_number(pool: Pool, limit: Any, integer: bool) -> object:
    """A number for a key whose values lie in ``limit`` (a Range, or None): seven times in ten in it, else absurd
    (NaN and ±inf among them; for an integer key, an integer of up to 5000 digits)."""
    if limit is not None and pool.random() < 0.7:
        value = limit.low + (limit.high - limit.low) * pool.random()
        return int(value) if integer else value
    if integer:
        return _huge_int(pool) if pool.random() < 0.3 else pool.below(2**63) - 2**62
    return pool.absurd()


def _text(pool: Pool) -> str:
    """One of :data:`TEXTS`, or (a fifth of the time) 20 random characters."""
    return TEXTS[pool.below(len(TEXTS))] if pool.random() < 0.8 else pool.rng.bytes(20).decode("latin-1")


def key_value(pool: Pool, key: Key) -> object:
    """A value for ``key``: of its type, in range or absurd; or (one time in ten) of another type, a huge integer,
    a list nested up to 5000 deep."""
    roll = pool.random()
    if roll < 0.08:
        return hostile_object(pool)
    if roll < 0.09:
        return _huge_int(pool)
    if roll < 0.095:
        return Nested(10 + pool.below(4990))
    default = key.default
    if isinstance(default, bool):
        return pool.random() < 0.5
    if isinstance(default, tuple):
        lengths = key.meta.get("lengths", range(4))
        n = lengths[pool.below(len(lengths))] if pool.random() < 0.8 else pool.below(MAX_LIST)
        if key.texts:
            return [_text(pool) for _ in range(n)]
        return [_key_number(pool, key.meta.get("range"), integer=False) for _ in range(n)]
    if isinstance(default, int | float):
        return _key_number(pool, key.meta.get("range"), integer=isinstance(default, int))
    return _text(pool)


def random_mapping(pool: Pool, sections: dict[str, list[Key]]) -> dict:
    """A configuration mapping of 1 to 5 tables of 1 to 8 keys: known ones mostly, now and then an unknown name or
    a table that is no table."""
    names = list(sections)
    data: dict[Any, Any] = {}
    for _ in range(1 + pool.below(5)):
        section = names[pool.below(len(names))] if pool.random() < 0.95 else _text(pool)
        if pool.random() < 0.02:
            data[section] = hostile_object(pool)
            continue
        keys = sections.get(section, [Key("unknown", 0.0, {}, False)])
        table = data
        for part in str(section).split("."):   # a sub-table inside its table; under a non-table, a throwaway
            table = table.setdefault(part, {}) if isinstance(table.get(part, {}), dict) else {}
        for _ in range(1 + pool.below(8)):
            key = keys[pool.below(len(keys))]
            table[key.name if pool.random() < 0.97 else _text(pool)] = key_value(pool, key)
    return data


def toml_literal(value: object) -> str:
    """``value`` as TOML writes it; what TOML cannot hold (None, bytes, an integer past 4300 digits) as text no
    parser takes or as 5000 nines."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return ("-" if value < 0 else "") + "9" * 5000 if value.bit_length() > 14_000 else str(value)
    if isinstance(value, float):
        return {"nan": "nan", "inf": "inf", "-inf": "-inf"}.get(repr(value), repr(value))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, Nested):
        return "[" * value.depth + "]" * value.depth
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_literal(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_literal(v)}" for k, v in value.items()) + "}"
    return repr(value)


def toml_text(data: dict, path: tuple[str, ...] = ()) -> str:
    """``data`` as a TOML file: top-level values first, then a ``[table]`` per table (``[table.sub]`` per sub-table,
    after its table's values)."""
    values = "".join(f"{json.dumps(str(k))} = {toml_literal(v)}\n" for k, v in data.items() if not isinstance(v, dict))
    header = f"[{'.'.join(json.dumps(part) for part in path)}]\n" if path else ""
    return header + values + "".join("\n" + toml_text(t, (*path, str(k))) for k, t in data.items()
                                     if isinstance(t, dict))


def hostile_toml(pool: Pool, text: str) -> bytes:
    """``text`` as bytes, now and then cut, bit-flipped, with garbage (not UTF-8) inserted, a table given twice or
    an array nested thousands deep."""
    data = bytearray(text.encode("utf-8", errors="surrogatepass"))
    roll = pool.random()
    if roll < 0.15 and data:
        del data[pool.below(len(data)):]
    elif roll < 0.3 and data:
        for _ in range(1 + pool.below(4)):
            data[pool.below(len(data))] ^= 1 << pool.below(8)
    elif roll < 0.4:
        at = pool.below(len(data) + 1)
        data[at:at] = pool.rng.bytes(1 + pool.below(63))
    elif roll < 0.45:
        depth = 100 + pool.below(4900)
        data += b"\n[fine.compass]\nlevel_sigma = " + b"[" * depth + b"]" * depth + b"\n"
    elif roll < 0.5:
        data += b"\n" + bytes(data)
    return bytes(data)


def _config_once(tally: Tally, pool: Pool, data: dict, path: Path) -> None:
    """``data`` into ``config_from_mapping``, or (every other input) as hostile TOML through ``load_config``."""
    if tally.inputs % 2:
        path.write_bytes(hostile_toml(pool, toml_text(data)))
        tally.attempt(partial(load_config, path), lambda: f"TOML file kept in {kept_copy([path])}", one_line=True)
    else:
        tally.attempt(partial(config_from_mapping, data), lambda: f"mapping {SHORT_REPR.repr(data)}", one_line=True)
    n = count_values(data)
    tally.inputs += 1
    tally.values += n


def fuzz_config(values: int = 200_000, seed: int = 0, advance: Advance = _ignore) -> Tally:
    """Random mappings (:func:`random_mapping`) into ``config_from_mapping`` and, every other input, as hostile TOML
    text (:func:`hostile_toml`) through ``load_config`` (the ``--config`` loader), until ``values`` numbers and texts
    have gone in; one line of ``ConfigError`` is the documented refusal."""
    tally = Tally("configuration (mappings, TOML files)", "values", (ConfigError,))
    pool = Pool(np.random.default_rng(seed))
    sections = _sections()
    with tempfile.TemporaryDirectory(prefix="sinsalign-fuzz-") as tmp, _timed(tally):
        path = Path(tmp) / "config.toml"
        while tally.values < values:
            before = tally.values
            _config_once(tally, pool, random_mapping(pool, sections), path)
            advance(tally.values - before)
    return tally


# --- every class, the table ---------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class FuzzClass:
    """One input class: its run, and whether its size is in inputs or in generated values."""

    run: Callable[[int, int, Advance], Tally]
    sized_by: str
    """"inputs" or "values"."""
    share: float
    """Its share of ``--inputs`` or ``--values``."""
    label: str


FUZZ_CLASSES: tuple[FuzzClass, ...] = (
    FuzzClass(fuzz_serial, "inputs", 1.0, "serial bytes"),
    FuzzClass(fuzz_messages, "inputs", 0.2, "msgpack messages"),
    FuzzClass(fuzz_samples, "values", 0.35, "sample stream"),
    FuzzClass(fuzz_aiding, "inputs", 0.2, "aiding epochs"),
    FuzzClass(fuzz_replay, "values", 0.45, "replay logs"),
    FuzzClass(fuzz_config, "values", 0.2, "configuration"),
    FuzzClass(fuzz_vendor_frames, "inputs", 0.2, "vendor IMU frames"),
)
"""The classes in the table's order; the shares of each size make up ``--inputs`` (the serial decoder's) and
``--values``."""


def class_size(spec: FuzzClass, inputs: int, values: int) -> int:
    """How many inputs or values ``spec`` runs for ``--inputs`` / ``--values``; at least 1."""
    return max(1, round(spec.share * (inputs if spec.sized_by == "inputs" else values)))


def run_all(inputs: int, values: int, seed: int = 0,
            progress: Callable[[FuzzClass, int], Advance] | None = None) -> list[Tally]:
    """Every class of :data:`FUZZ_CLASSES` at its size; ``progress(spec, size)`` gives each run its
    :data:`Advance`."""
    tallies = []
    for spec in FUZZ_CLASSES:
        size = class_size(spec, inputs, values)
        tallies.append(spec.run(size, seed, progress(spec, size) if progress else _ignore))
    return tallies


TLS_ROW = ("| TLS peers (Zenoh connections) | not fuzzed | — | — | — | `tests/daemon/test_security.py`: without a "
           "certificate of the CA no connection opens; a CA-signed client without rights gets nothing and feeds "
           "nothing | — | — |")
"""The input class the fuzzer does not reach: who may open a session at all, held by mutual TLS and access
control, and tested on the real daemon."""


@contextlib.contextmanager
def progress_bar(show: bool) -> Iterator[Callable[[FuzzClass, int], Advance]]:
    """A rich progress bar on stderr, a line per class as it starts (``show`` False: none); yields what
    :func:`run_all` takes as ``progress``. Its console holds the real stderr, so the replay's notices, caught from
    ``sys.stderr`` meanwhile, do not take the bar with them."""
    columns = (TextColumn("{task.description:<18}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[unit]}"), TimeElapsedColumn())
    with Progress(*columns, console=Console(file=sys.stderr), disable=not show) as bar:
        def start(spec: FuzzClass, size: int) -> Advance:
            return partial(bar.advance, bar.add_task(spec.label, total=size, unit=spec.sized_by))
        yield start


def _number(n: float) -> str:
    """A count with thin groups of three digits (the results' style): 1 234 567."""
    return f"{n:,.0f}".replace(",", " ")


def _counters_text(counters: Counter[str]) -> str:
    return ", ".join(f"{name} {_number(count)}" for name, count in counters.items()) or "—"


def _refusal_text(tally: Tally) -> str:
    if not tally.refusal:
        return "— (nothing refused: dropped and counted)"
    return ", ".join(f"{_number(n)} `{name}`" for name, n in tally.refusals.most_common()) or "0"


def table_row(k: int, tally: Tally) -> str:
    """The table's row of one class."""
    escaped = f"**{_number(tally.escaped)}**"
    return (f"| {k}. {tally.name} | {_number(tally.inputs)} | {_number(tally.values)} {tally.unit} | "
            f"{_number(tally.accepted)} | {_counters_text(tally.counters)} | {_refusal_text(tally)} | {escaped} | "
            f"{tally.seconds:.1f} |")


def fault_table(tallies: Sequence[Tally], provenance: str, seed: int) -> str:
    """The Markdown fault table headed by ``provenance`` (the command and its commit), the TLS row, and a line with
    the run's totals."""
    generated = sum(t.values for t, spec in zip(tallies, FUZZ_CLASSES, strict=True) if spec.sized_by == "values")
    lines = [provenance, "",
             "| input class | inputs | values | accepted | dropped or counted (the service's counters) | "
             "refused (documented error) | escaped | s |",
             "|---|---|---|---|---|---|---|---|",
             *(table_row(k, t) for k, t in enumerate(tallies, 1)), TLS_ROW, "",
             f"Seed {seed}; {_number(generated)} generated values in classes 3, 5 and 6; "
             f"{sum(t.seconds for t in tallies):.0f} s in all. Escaped: any other exception (for the sample stream "
             "also a non-finite record, or no record after the last fault)."]
    return "\n".join(lines)
