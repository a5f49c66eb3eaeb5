"""The alignment modes, one file each, and the registry that picks one from the aids given.

A mode declares what the one pipeline (service/pipeline.py) runs: the aiding it takes, its coarse stage
(observation source, solver, σ model), its fine stage and measurements, its hand-over and its counters
(:class:`~service.pipeline.Mode`). A module here that names its mode class ``MODE`` is a mode: adding one is a
file and its tests. The aiding kinds its ``aids`` declare are the combination that selects it; the pipeline's
:func:`~service.pipeline.build_pipeline` builds the one the aids select.
"""
from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..pipeline import AlignmentPipeline, Mode


def _discover() -> dict[frozenset[str], Callable[[AlignmentPipeline], Mode]]:
    """Every module of this package with a ``MODE``, keyed by the aiding kinds it takes; two modes for one
    combination are a programming error, raised at import."""
    modes: dict[frozenset[str], Callable[[AlignmentPipeline], Mode]] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        mode = getattr(importlib.import_module(f"{__name__}.{info.name}"), "MODE", None)
        if mode is None:
            continue
        kinds = frozenset(kind for kind, _ in mode.aids)
        if kinds in modes:
            raise ImportError(f"modes {modes[kinds].__name__} and {mode.__name__} both take {sorted(kinds)}")
        modes[kinds] = mode
    return modes


MODES = _discover()
"""Which mode the aids given select (``replay --aid``, the daemon's ``aid/<kind>`` inputs)."""
