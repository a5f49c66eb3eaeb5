"""``sinsalign eval``: a scenario's Monte Carlo table (and its seed sets, error budget, compass and solver tables), or
an aided mode's own table of fixed variants, printed and saved with its plot, stamped with the command and commit."""
from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from pathlib import Path

from sinsalign.service.config import Config, ConfigError

from .stamp import stamp

AIDED_TABLES = {"seed003": ("evaluate_aided.seed003_table", "evaluate_aided.plot_seed003"),
                "seed002": ("evaluate_transfer.seed002_table", "evaluate_transfer.plot_seed002"),
                "seed004": ("evaluate_gnss.seed004_table", "evaluate_gnss.plot_seed004"),
                "seed004-rates": ("evaluate_gnss.rate_table", "evaluate_gnss.plot_rates"),
                "seed002-rates": ("evaluate_transfer.rate_table", "evaluate_gnss.plot_rates"),
                "transfer-mems": ("evaluate_transfer.handover_table", "evaluate_transfer.plot_handover"),
                "seed003-odo-gnss": ("evaluate_odo_gnss.odo_gnss_table", "evaluate_odo_gnss.plot_odo_gnss"),
                "honesty": ("honesty.honesty_table", "honesty.plot_honesty")}
"""``eval`` names that run an aided mode's own table of fixed variants: its table and plot (module.function in
sinsalign.tools)."""


def _tool(name: str) -> Callable:
    """The function ``module.function`` of sinsalign.tools, imported on demand (the tools pull in matplotlib)."""
    module, function = name.rsplit(".", 1)
    return getattr(importlib.import_module(f"sinsalign.tools.{module}"), function)


def _aided_table(name: str, seeds: range, out: Path, provenance: str) -> None:
    """The aided modes' own tables (seed002: master INS, seed003: odometer, seed004: GNSS, seed004-rates and
    seed002-rates: slower GNSS receivers and master INS, seed003-odo-gnss: odometer and GNSS together) and plots."""
    table, plot = (_tool(f) for f in AIDED_TABLES[name])
    text, runs = table(seeds)
    if name == "seed002":
        from .evaluate_transfer import phase1_comparison
        text += "\n\n" + phase1_comparison(seeds)
    _write_table(name, text, out, plot(runs, out / f"{name}_heading.png"), provenance)


def _write_table(name: str, text: str, out: Path, png: Path, provenance: str) -> None:
    """Print an eval's tables and save them as OUT/NAME.md, both headed by ``provenance`` (the command line and the
    commit it started on)."""
    text = f"{provenance}\n\n{text}"
    (out / f"{name}.md").write_text(text + "\n")
    print(text)
    print(f"\nplot: {png}\ntable: {out / f'{name}.md'}")


def run_eval(argv: Sequence[str], scenario: str, seeds: range, seeds_per_set: int, out: Path, config: Config,
             customised: bool, budget: bool = False, fine: bool = False, solvers: bool = False) -> None:
    """The eval of ``scenario`` over ``seeds`` (sets of ``seeds_per_set``) with ``config`` into ``out``; ``argv`` the
    command line for the stamp, ``customised`` whether a file or option changed the configuration (an aided mode's
    table runs its own, and refuses)."""
    from .evaluate import (
        budget_table,
        fine_table,
        monte_carlo,
        plot_fine,
        plot_heading,
        scenario_table,
        seed_set_table,
        solver_table,
    )
    provenance = stamp(argv)   # the commit the runs start on
    aided = scenario in AIDED_TABLES
    if aided and (customised or solvers or fine or len(seeds) > seeds_per_set or budget):
        raise ConfigError(f"eval {scenario} runs its table's own configurations; --config, the alignment "
                          "options, --solvers, --fine, --seed-sets and --budget apply to a single scenario "
                          "(sinsalign sim --list)")
    out.mkdir(parents=True, exist_ok=True)
    if aided:
        _aided_table(scenario, seeds, out, provenance)
        return
    runs = monte_carlo(scenario, seeds, config.as_dict())
    text = scenario_table(scenario, runs)
    if len(seeds) > seeds_per_set:
        text += "\n\n" + seed_set_table(scenario, runs, seeds_per_set)
    others = None
    if budget:
        text += "\n\n" + budget_table(scenario, runs, config.as_dict())[0]
    if fine:
        table, fine_runs = fine_table(scenario, seeds)
        text += "\n\n" + table
        print(f"plot: {plot_fine(scenario, fine_runs, out / f'{scenario}_fine.png')}")
    if solvers:
        table, all_runs = solver_table(scenario, seeds)
        text += "\n\n" + table
        others = {k: v for k, v in all_runs.items() if k != "OPREQ"}
    _write_table(scenario, text, out, plot_heading(scenario, runs, out / f"{scenario}_heading.png", others),
                 provenance)
