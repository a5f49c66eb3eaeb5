"""Replay an IMU log through the alignment pipeline as fast as possible, writing JSON Lines."""
from __future__ import annotations

import os
import sys
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from sinsalign.protocol.aiding_log import KINDS, open_aiding_log
from sinsalign.protocol.imu_log import LogFormatError, open_imu_log
from sinsalign.protocol.read_ahead import read_ahead
from sinsalign.protocol.results import ResultRecord
from sinsalign.service.aiding import AidingFeed, AidingTrack, aid_rows
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.earth import Site
from sinsalign.service.config import Config, ConfigError, config_from_mapping
from sinsalign.service.pipeline import build_pipeline
from sinsalign.service.restarting import RestartingPipeline
from sinsalign.service.safe_files import open_private
from sinsalign.service.sample_gate import gate_for


@dataclass(frozen=True, slots=True)
class ReplaySummary:
    samples: int
    records: int
    last: ResultRecord | None
    stages: str   # what ran (AlignmentPipeline.stages_text)
    gate: dict[str, int]   # the sample gate's counters that are not zero (gaps bridged, restarts, drops)


def parse_aids(specs: list[str] | None) -> dict[str, str]:
    """``["odo=ODO.csv", …]`` → {"odo": "ODO.csv"}; a bad spec or a kind given twice is a ConfigError."""
    aids: dict[str, str] = {}
    for spec in specs or []:
        kind, sep, path = spec.partition("=")
        if not sep or not path or kind not in KINDS:
            raise ConfigError(f"--aid {spec!r}: expected KIND=FILE with KIND one of {', '.join(KINDS)}")
        if kind in aids:
            raise ConfigError(f"--aid {kind}: given twice")
        aids[kind] = path
    return aids


def open_aids(aids: dict[str, str], config: Config) -> tuple[Config, dict[str, AidingFeed]]:
    """Each aiding log opened as a feed (latency, gaps from the configuration; every epoch held to what its kind of
    source can report); the configuration with what the logs state of themselves (their noise, a GNSS or master
    log's lever arm), validated as the configuration is."""
    feeds = {}
    for kind, path in aids.items():
        log = open_aiding_log(kind, path)
        feeds[kind] = AidingFeed(AidingTrack.configured(kind, config.aiding), log.blocks(limits=log.kind.limits))
        config = config_from_mapping({"aiding": {kind: log.stated()}}, config)
    return config, feeds


def _open_partial(partial: Path, out_path: Path) -> TextIO:
    """The temporary results file: created afresh, owner-only, never through a symbolic link (one planted at the
    predictable name would have the replay overwrite what it points at)."""
    try:
        return open_private(partial, exclusive=True)
    except FileExistsError:
        raise OSError(f"{partial} exists: another replay is writing {out_path.name}, or one was stopped; remove it "
                      "if not") from None


class _NoBar:
    """What :func:`_progress_bar` hands out when nothing is shown: rich is then never imported (start-up time)."""

    def __enter__(self) -> _NoBar:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def add_task(self, *args: Any, **kwargs: Any) -> int:
        return 0

    def update(self, *args: Any, **kwargs: Any) -> None:
        return None


def _progress_bar(show: bool) -> Any:
    """The replay's progress bar on stderr (rich), or a bar that shows nothing."""
    if not show:
        return _NoBar()
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
    return Progress(TextColumn("replay"), BarColumn(), TextColumn("{task.fields[info]}"), TimeRemainingColumn(),
                    transient=True)


def replay(imu_csv: str | Path, out_jsonl: str | Path, config: Config, progress: bool | None = None,
           aids: dict[str, str] | None = None) -> ReplaySummary:
    """Process ``imu_csv`` (with aiding logs ``aids``: kind → path) and write one result per output
    epoch to ``out_jsonl``.

    The log's samples go through the daemon's sample gate, as a live line's do: a gap of a few samples is bridged,
    a longer one starts the alignment over, an increment beyond the configured IMU's range is dropped; a daemon's
    recording (its admitted samples, its restart marks) replays as it ran.

    Raises LogFormatError (file, line, column named) on a malformed log or a sample no IMU can measure;
    ``out_jsonl`` is then left as it was (results go to a temporary file that replaces it only on success).
    """
    log = open_imu_log(imu_csv)
    h = log.header
    config, feeds = open_aids(aids or {}, config)
    site = Site(h.lat_deg * DEG, h.lon_deg * DEG, h.height_m)
    # a daemon's recording marks where it started over; a failed step starts over here as it does there
    def notice(text: str) -> None:
        print(f"replay: {text}", file=sys.stderr)

    alignment = RestartingPipeline(lambda: build_pipeline(config, site, h.rate_hz, h.datasheet(), feeds), notice)
    gate = gate_for(config, h.rate_hz)
    size = max(Path(imu_csv).stat().st_size, 1)
    show = sys.stderr.isatty() if progress is None else progress
    samples = records = 0
    last = None
    out_path = Path(out_jsonl)
    partial = out_path.with_name(f".{out_path.name}.partial")
    out = _open_partial(partial, out_path)
    try:
        # the reading thread stops with the replay, however it ends
        with out, _progress_bar(show) as bar, closing(read_ahead(log.row_segments(limits=log.limits))) as blocks:
            task = bar.add_task("replay", total=size, info="")
            for restart, rows in blocks:
                if restart is not None:
                    alignment.restart()
                    gate.new_time_base()
                samples += len(rows)
                segments = gate.admit(rows)
                if gate.rate.failure is not None:
                    raise LogFormatError(imu_csv, log.first_line, "t", f"{gate.rate.failure}: state the data's rate",
                                         "sample " if log.binary else "")
                for segment in segments:
                    if segment.restart:
                        notice(segment.reason)
                        alignment.restart()
                    t = segment.rows[:, 0]
                    aid = aid_rows(feeds, alignment.pipeline.aid_kinds, t)
                    for record in alignment.process(t, segment.rows[:, 1:4], segment.rows[:, 4:7], aid)[0]:
                        out.write(record.to_json() + "\n")
                        records += 1
                        last = record
                    alignment.report_events()
                if len(rows):
                    bar.update(task, completed=min(size, samples * 150), info=f"t = {rows[-1, 0]:.0f} s")
        os.replace(partial, out_path)
    finally:
        partial.unlink(missing_ok=True)
    return ReplaySummary(samples, records, last, alignment.pipeline.stages_text(),
                         {name: value for name, value in gate.counters.as_dict().items() if value})
