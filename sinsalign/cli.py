"""The ``sinsalign`` command: one entry point, a subcommand per job."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

DESCRIPTION = """\
Real-time initial alignment of a strapdown INS: recursive Optimal-REQUEST (OPREQ) coarse
alignment in the inertial frame (level from gravity, heading from the Earth's rotation), then
compass (gyrocompass-loop) fine alignment with stored-data backward/forward passes.
Output phases: coarse -> fine -> aligned.

Conventions: navigation frame East-North-Up, body Right-Front-Up, q = [w, x, y, z] of C_b^n,
heading clockwise from true North in [0, 360). IMU logs are CSV of angle and velocity increments.

Typical session:
  sinsalign sim seed000-swing --seed 1 --out-dir run1     # simulate a ship on a swing base
  sinsalign replay run1/imu.csv --out run1/results.jsonl   # align it as fast as the CPU goes
  sinsalign eval seed000-swing --seeds 20 --no-fine         # Monte Carlo table and plot (OPREQ)
  sinsalign eval seed001-swing --fine                       # seed 001's compass comparison
  sinsalign demo                                            # all of it, one run, summary
"""


def _overrides(args: argparse.Namespace) -> dict:
    alignment = {k: v for k, v in (("solver", args.solver), ("request_rho", args.rho),
                                   ("obs_interval_s", args.obs_interval)) if v is not None}
    out = {"alignment": alignment} if alignment else {}
    fine = {k: v for k, v in (("enabled", False if args.no_fine else None), ("stored_pairs", args.stored_pairs))
            if v is not None}
    if fine:
        out["fine"] = fine
    if getattr(args, "period", None) is not None:
        out["output"] = {"period_s": args.period}
    return out


def _add_alignment_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("alignment (override the configuration file)")
    g.add_argument("--config", metavar="FILE", help="TOML configuration (see README, 'Configuration')")
    g.add_argument("--solver", choices=("opreq", "request", "qmethod"),
                   help="opreq: optimal fading gain (default); request: fixed gain --rho; qmethod: batch OBA")
    g.add_argument("--rho", type=float, help="fixed fading gain of --solver request, e.g. 0.01")
    g.add_argument("--obs-interval", type=float, metavar="S", help="seconds between vector observations (0.1)")
    g.add_argument("--no-fine", action="store_true", help="OPREQ coarse alignment only (no compass hand-over)")
    g.add_argument("--stored-pairs", type=int, metavar="N",
                   help="backward+forward passes over the stored first 80 s (default 3; 0 = none)")


def cmd_sim(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from sinsalign.tools.sim.files import write_simulation
    from sinsalign.tools.sim.scenarios import SCENARIOS, get_scenario
    if args.list or not args.scenario:
        for name, s in SCENARIOS.items():
            print(f"{name:22s} {s.description}")
        print("\nEach name also runs without sensor errors as NAME-ideal.")
        return 0
    scenario = get_scenario(args.scenario)
    if args.duration:
        scenario = replace(scenario, duration_s=args.duration)
    files = write_simulation(scenario, args.seed, args.out_dir)
    print(f"wrote {files.imu_csv} and {files.truth_csv} ({scenario.duration_s:g} s at {scenario.rate_hz:g} Hz)")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from sinsalign.service.config import load_config
    from sinsalign.tools.replay import replay
    config = load_config(args.config, _overrides(args))
    start = time.perf_counter()
    summary = replay(args.imu_csv, args.out, config, progress=None if not args.no_progress else False)
    elapsed = time.perf_counter() - start
    last = summary.last
    print(f"{summary.samples} samples → {summary.records} results in {args.out} "
          f"({summary.samples / max(elapsed, 1e-9):,.0f} frames/s)", file=sys.stderr)
    if last is not None:
        print(f"t = {last.t:g} s: heading {last.heading_deg:.4f}° ± {last.heading_sigma_deg:.4f}°, "
              f"pitch {last.pitch_deg:.4f}°, roll {last.roll_deg:.4f}° (level σ {last.level_sigma_deg:.4f}°), "
              f"converged: {last.converged}", file=sys.stderr)
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    from sinsalign.tools.evaluate import fine_table, monte_carlo, plot_fine, plot_heading, scenario_table, solver_table
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    runs = monte_carlo(args.scenario, seeds, _overrides(args))
    text = scenario_table(args.scenario, runs)
    others = None
    if args.fine:
        table, fine_runs = fine_table(args.scenario, seeds)
        text += "\n\n" + table
        print(f"plot: {plot_fine(args.scenario, fine_runs, out / f'{args.scenario}_fine.png')}")
    if args.solvers:
        table, all_runs = solver_table(args.scenario, seeds)
        text += "\n\n" + table
        others = {k: v for k, v in all_runs.items() if k != "OPREQ"}
    png = plot_heading(args.scenario, runs, out / f"{args.scenario}_heading.png", others)
    (out / f"{args.scenario}.md").write_text(text + "\n")
    print(text)
    print(f"\nplot: {png}\ntable: {out / (args.scenario + '.md')}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from sinsalign.tools.benchmark import bench_latency, bench_replay, bench_stream_memory
    r = bench_replay(duration_s=args.seconds)
    print(f"replay (CSV → JSONL) of {r.samples} frames: {r.frames_per_s:,.0f} frames/s; "
          f"pipeline alone {r.samples / r.pipeline_seconds:,.0f} frames/s")
    lat = bench_latency()
    print("live path, one sample per call: p50 {p50_us:.0f} µs, p99 {p99_us:.0f} µs, max {max_us:.0f} µs "
          "(budget at 200 Hz: {budget_200hz_us:.0f} µs)".format(**lat))
    if args.stream_hours > 0:
        start = time.perf_counter()
        samples = bench_stream_memory(args.stream_hours)
        elapsed = time.perf_counter() - start
        first = samples[0][1]
        for hour, rss in samples:
            print(f"  stream hour {hour:5.1f}: RSS {rss:7.1f} MiB")
        print(f"{args.stream_hours:g} h stream in {elapsed:.0f} s: RSS growth {samples[-1][1] - first:+.2f} MiB "
              f"after the first hour")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from sinsalign.protocol.imu_log import TRUTH_COLUMNS, open_imu_log, read_header, read_rows
    from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
    from sinsalign.service.align.sensor_model import physical_limit
    from sinsalign.service.config import Config
    from sinsalign.tools.replay import replay
    from sinsalign.tools.sim.files import simulated_biases, write_simulation
    from sinsalign.tools.sim.scenarios import get_scenario

    out = Path(args.out_dir)
    scenario = get_scenario("seed000-swing")
    print(f"1/3 simulating {scenario.name} (seed {args.seed}): {scenario.description}")
    files = write_simulation(scenario, args.seed, out)
    print(f"2/3 replaying {files.imu_csv} → {out / 'results.jsonl'}")
    replay(files.imu_csv, out / "results.jsonl", Config())
    print("3/3 comparing with the truth")
    with open(out / "results.jsonl") as f:
        rows = [json.loads(line) for line in f]
    with open(files.truth_csv) as f:
        _, consumed = read_header(f, str(files.truth_csv), TRUTH_COLUMNS, required=())
        truth = np.concatenate(list(read_rows(f, str(files.truth_csv), consumed + 1, TRUTH_COLUMNS)))
    index = {round(t, 6): k for k, t in enumerate(truth[:, 0])}
    gyro_b, acc_b = simulated_biases(open_imu_log(files.imu_csv).header)
    C_true = dcm_from_quat(truth[:, 4:8])
    C_mean = C_true.mean(axis=0)
    limit = physical_limit(C_mean @ acc_b, C_mean @ gyro_b, scenario.site.lat, scenario.site.gravity) / DEG
    print("\n   t (s)  phase    heading (°)   error φ_U (°)  error − limit (°)   σ (°)   converged")
    for r in rows:
        if r["t"] in (10, 20, 30, 60, 100, 150, 200):
            k = index[round(r["t"], 6)]
            phi = misalignment(dcm_from_quat(np.array(r["q"])), C_true[k]) / DEG
            print(f"  {r['t']:6.0f}  {r['phase']:7s}  {r['heading_deg']:11.4f}  {phi[2]:+14.4f}  "
                  f"{phi[2] - limit[2]:+16.4f}  "
                  f"{r['heading_sigma_deg']:7.4f}   {r['converged']}")
    print(f"\nphysical limit of this run (sensor biases): heading {limit[2]:+.4f}°, "
          f"level E {limit[0]:+.4f}° N {limit[1]:+.4f}°")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sinsalign", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("sim", help="simulate an IMU log and its truth from a named scenario",
                       description="Write OUT_DIR/imu.csv (pinned IMU log, with the datasheet grade and the actual "
                       "simulated biases in its comments) and OUT_DIR/imu_truth.csv. Increments are exact "
                       "(Gauss-Legendre integrals of the analytic motion). --list shows the scenarios.")
    p.add_argument("scenario", nargs="?", help="scenario name, e.g. seed000-swing, static, seed000-turntable")
    p.add_argument("--seed", type=int, default=1, help="noise seed (default 1)")
    p.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration")
    p.add_argument("--out-dir", default="out/sim", help="output folder (default out/sim)")
    p.add_argument("--list", action="store_true", help="list the scenarios")
    p.set_defaults(func=cmd_sim)

    p = sub.add_parser("replay", help="align a recorded IMU log as fast as possible → JSON Lines",
                       description="Process IMU.csv (pinned log format) and write one JSON object per output epoch "
                       "(t on whole multiples of the output period) with q, Euler angles, heading/level σ, "
                       "phase and converged. A malformed log stops with the file, line and column named.")
    p.add_argument("imu_csv", metavar="IMU.csv")
    p.add_argument("--out", required=True, metavar="RESULTS.jsonl")
    p.add_argument("--period", type=float, metavar="S", help="output period (default 1 s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_alignment_options(p)
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("eval", help="Monte Carlo against simulated truth: table, settling, σ honesty, plot",
                       description="Run N seeds of a scenario in memory; print a paper-style table of heading and "
                       "level errors relative to each run's physical limit, settling time and how honest σ is; "
                       "save OUT_DIR/SCENARIO_heading.png and OUT_DIR/SCENARIO.md.")
    p.add_argument("scenario")
    p.add_argument("--seeds", type=int, default=20, help="number of seeds (default 20)")
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--solvers", action="store_true", help="also compare OPREQ, q-method and REQUEST gains")
    p.add_argument("--fine", action="store_true", help="also run seed 001's comparison: OPREQ only, compass alone "
                   "from 1.5°, OPREQ → compass, each with and without stored data; table and plot")
    p.add_argument("--out-dir", default="out/eval")
    _add_alignment_options(p)
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser("bench", help="benchmarks: replay frames/s, per-sample latency, RSS over a long stream",
                       description="Numbers, not pass/fail. --stream-hours 24 streams a day of 200-Hz data "
                       "generated on the fly and reports RSS every simulated hour.")
    p.add_argument("--seconds", type=float, default=600.0, help="length of the replayed log (default 600 s)")
    p.add_argument("--stream-hours", type=float, default=0.0, help="hours of streamed data (0 = skip; try 24)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("demo", help="the main job: simulate a seed-000 swing run, replay it, report against truth",
                       description="Simulate the seed-000 swing-base scenario, replay it through the alignment and "
                       "print the heading error against the simulated truth and the run's physical limit.")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out-dir", default="out/demo")
    p.set_defaults(func=cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    from sinsalign.protocol.imu_log import LogFormatError
    from sinsalign.service.config import ConfigError
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except (LogFormatError, ConfigError, KeyError, OSError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"sinsalign {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
