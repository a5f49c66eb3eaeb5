"""The alignment modes, one file each, and the registry that picks one from the aids given.

A mode declares what the one pipeline (service/pipeline.py) runs: the aiding it takes, its coarse stage
(observation source, solver, σ model), its fine stage and measurements, its hand-over and its counters
(:class:`~service.pipeline.Mode`). Adding a mode is a file here and a line in :data:`MODES`; the pipeline's
:func:`~service.pipeline.build_pipeline` builds the one the aids select.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from .fixed_base import FixedBase
from .gnss import Gnss
from .odometer import Odometer
from .odometer_gnss import OdometerGnss
from .transfer import Transfer

if TYPE_CHECKING:
    from ..pipeline import AlignmentPipeline, Mode

MODES: dict[frozenset[str], Callable[[AlignmentPipeline], Mode]] = {
    frozenset(): FixedBase, frozenset({"odo"}): Odometer, frozenset({"gnss"}): Gnss,
    frozenset({"master"}): Transfer, frozenset({"odo", "gnss"}): OdometerGnss}
"""Which mode the aids given select (``replay --aid``, the daemon's ``aid/<kind>`` inputs)."""
