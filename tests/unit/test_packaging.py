"""The install ships every package of the tree: a wheel (``pip install .``, not the editable install the tests run
from) carries only the packages pyproject.toml lists, and one left out fails at import on the user's machine.

GIVEN the folders pyproject.toml maps to ``sinsalign.*``, WHEN every folder below them that holds an __init__.py is
named as its package, THEN pyproject.toml lists each of them, and lists nothing that is not there.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_every_package_of_the_tree_is_listed_for_the_install() -> None:
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = set()
    for package, folder in setuptools["package-dir"].items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            parts = init.parent.relative_to(base).parts
            if "__pycache__" not in parts:
                found.add(".".join((package, *parts)))
    assert set(setuptools["packages"]) == found
