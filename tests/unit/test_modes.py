"""The mode registry: every module under service/modes/ that declares a MODE is found, keyed by its aids."""
from __future__ import annotations

import importlib
import pkgutil
import types
from pathlib import Path

import pytest
import sinsalign.service.modes as modes_package
from sinsalign.service.modes import MODES

MODE_FILES = sorted(p.stem for p in Path(modes_package.__file__).parent.glob("*.py")
                    if p.stem not in ("__init__", "kalman"))


def test_every_mode_file_is_registered_under_its_aids() -> None:
    found = {mode.__module__.rsplit(".", 1)[-1]: kinds for kinds, mode in MODES.items()}
    assert sorted(found) == MODE_FILES
    for kinds, mode in MODES.items():
        assert kinds == frozenset(kind for kind, _ in mode.aids)


def test_the_combinations_are_the_documented_ones() -> None:
    assert set(MODES) == {frozenset(), frozenset({"odo"}), frozenset({"gnss"}), frozenset({"odo", "gnss"}),
                          frozenset({"master"})}


def test_two_modes_for_one_combination_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A second module whose mode takes the GNSS mode's aids stops the import with both names."""
    from sinsalign.service.modes.gnss import Gnss

    class AnotherGnss(Gnss):
        pass

    modules = [*pkgutil.iter_modules(modes_package.__path__), pkgutil.ModuleInfo(None, "zz_twin", False)]
    real_import = importlib.import_module
    monkeypatch.setattr(modes_package.pkgutil, "iter_modules", lambda path: modules)
    monkeypatch.setattr(modes_package.importlib, "import_module", lambda name: (
        types.SimpleNamespace(MODE=AnotherGnss) if name.endswith(".zz_twin") else real_import(name)))
    with pytest.raises(ImportError, match="Gnss and AnotherGnss both take"):
        modes_package._discover()
