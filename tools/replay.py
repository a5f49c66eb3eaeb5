"""Replay an IMU log through the alignment pipeline as fast as possible, writing JSON Lines."""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.protocol.results import ResultRecord
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.earth import Site
from sinsalign.service.config import Config
from sinsalign.service.pipeline import AlignmentPipeline


@dataclass(frozen=True, slots=True)
class ReplaySummary:
    samples: int
    records: int
    last: ResultRecord | None


def replay(imu_csv: str | Path, out_jsonl: str | Path, config: Config, progress: bool | None = None) -> ReplaySummary:
    """Process ``imu_csv`` and write one result per output epoch to ``out_jsonl``.

    Raises LogFormatError (file, line, column named) on a malformed log; ``out_jsonl`` is then
    left as it was (results go to a temporary file that replaces it only on success).
    """
    log = open_imu_log(imu_csv)
    h = log.header
    pipeline = AlignmentPipeline(config, Site(h.lat_deg * DEG, h.lon_deg * DEG, h.height_m), h.rate_hz,
                                 h.datasheet())
    size = max(Path(imu_csv).stat().st_size, 1)
    show = sys.stderr.isatty() if progress is None else progress
    samples = records = 0
    last = None
    out_path = Path(out_jsonl)
    partial = out_path.with_name(f".{out_path.name}.partial")
    try:
        with open(partial, "w", encoding="utf-8") as out, Progress(
                TextColumn("replay"), BarColumn(), TextColumn("{task.fields[info]}"), TimeRemainingColumn(),
                disable=not show, transient=True) as bar:
            task = bar.add_task("replay", total=size, info="")
            for t, dtheta, dv in log.blocks():
                for record in pipeline.process(t, dtheta, dv):
                    out.write(record.to_json() + "\n")
                    records += 1
                    last = record
                samples += len(t)
                bar.update(task, completed=min(size, samples * 150), info=f"t = {t[-1]:.0f} s")
        os.replace(partial, out_path)
    finally:
        partial.unlink(missing_ok=True)
    return ReplaySummary(samples, records, last)
