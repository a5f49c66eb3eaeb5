"""The ``sinsalign`` command: one entry point, a subcommand per job."""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

from sinsalign.protocol.formats import GNSS_INPUTS, IMU_FORMATS

DESCRIPTION = """\
Real-time initial alignment of a strapdown INS: recursive Optimal-REQUEST (OPREQ) coarse
alignment in the inertial frame (level from gravity, heading from the Earth's rotation; GLS
instead where the datasheet's gyro walk dominates), then compass (gyrocompass-loop) fine
alignment with stored-data backward/forward passes.
Output phases: coarse -> fine -> aligned (or disturbed when the base moves).
Runs as a daemon (serial/Zenoh in, Zenoh out) or offline on recorded logs, with the same results.

Conventions: navigation frame East-North-Up, body Right-Front-Up, q = [w, x, y, z] of C_b^n,
heading clockwise from true North in [0, 360). IMU logs are CSV of angle and velocity increments.

Typical session:
  sinsalign sim seed000-swing --seed 1 --out-dir run1     # simulate a ship on a swing base
  sinsalign replay run1/imu.csv --out run1/results.jsonl   # align it as fast as the CPU goes
  sinsalign eval seed000-swing --seeds 20 --no-fine         # Monte Carlo table and plot (coarse stage)
  sinsalign eval seed001-swing --fine                       # seed 001's compass comparison
  sinsalign eval seed000-swing --no-fine --budget          # which IMU error the heading's figures come from
  sinsalign demo                                            # the live bench in one command
  sinsalign config --config my.toml                         # the configuration in effect, every key

Live:
  sinsalign bench --speed 1                      # virtual IMU on a new pty; prints its name
  sinsalign serve --serial /dev/pts/N            # the daemon (Zenoh peer on tcp/127.0.0.1:7447)
  sinsalign serve --serial /dev/pts/N --aid gnss # in flight: GNSS on <prefix>/<unit>/aid/gnss or serial frames
  sinsalign watch                                # live view; any number of them
"""


def _number_above(minimum: float, inclusive: bool = False, kind: type = float) -> Callable[[str], float]:
    """An argparse type: a finite number above ``minimum`` (or at it, if ``inclusive``), else a usage error."""
    bound = f"{'at least' if inclusive else 'above'} {minimum:g}"

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a{'n integer' if kind is int else ' number'}") from None
        if not (value >= minimum if inclusive else value > minimum) or value != value or abs(value) == float("inf"):
            raise argparse.ArgumentTypeError(f"{text} must be {bound}")
        return value
    return parse


POSITIVE = _number_above(0.0)
NON_NEGATIVE = _number_above(0.0, inclusive=True)
POSITIVE_INT = _number_above(1, inclusive=True, kind=int)
SEED = _number_above(0, inclusive=True, kind=int)


def _overrides(args: argparse.Namespace) -> dict:
    alignment = {k: v for k, v in (("solver", args.solver), ("request_rho", args.rho),
                                   ("obs_interval_s", args.obs_interval),
                                   ("swing_bias", args.swing_bias)) if v is not None}
    out = {"alignment": alignment} if alignment else {}
    fine: dict = {"enabled": False} if args.no_fine else {}
    if args.stored_pairs is not None:
        fine["compass"] = {"stored_pairs": args.stored_pairs}
    if fine:
        out["fine"] = fine
    if getattr(args, "period", None) is not None:
        out["output"] = {"period_s": args.period}
    return out


def _add_alignment_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("alignment (override the configuration file)")
    g.add_argument("--config", metavar="FILE", help="TOML configuration (see docs/reference.md, 'Configuration')")
    g.add_argument("--solver", choices=("auto", "opreq", "request", "qmethod", "centred", "gls"),
                   help="auto (default): opreq, or gls where the datasheet's gyro angle random walk dominates the "
                   "heading noise; opreq: optimal fading gain; request: fixed gain --rho; qmethod: batch OBA; "
                   "centred: Wahba with a free constant offset (for the aided modes); gls: generalised least "
                   "squares on whitened α increments (fixed base, at the gyro's noise floor:"
                   " docs/algorithms/coarse.md)")
    g.add_argument("--rho", type=float, help="fixed fading gain of --solver request, e.g. 0.01")
    g.add_argument("--obs-interval", type=float, metavar="S", help="seconds between vector observations (0.1)")
    g.add_argument("--swing-bias", action=argparse.BooleanOptionalAction, default=None,
                   help="estimate the accelerometer bias seen through a swinging body and take its term out of the "
                   "coarse stage's vectors (on by default; fixed base; removes a slow heading transient on a "
                   "swinging base, see docs/algorithms/coarse.md); --no-swing-bias leaves the vectors as integrated")
    g.add_argument("--no-fine", action="store_true", help="coarse alignment only (no compass hand-over)")
    g.add_argument("--stored-pairs", type=int, metavar="N",
                   help="backward+forward passes over the stored first 80 s (default 3; 0 = none)")


FIXED_BASE_OPTIONS = {"solver": "--solver", "rho": "--rho", "stored_pairs": "--stored-pairs",
                      "swing_bias": "--[no-]swing-bias"}
"""Options of the fixed-base stages (OPREQ and its alternatives, the compass stage's stored data)."""


def _refuse_fixed_base_options(args: argparse.Namespace, aided: bool) -> None:
    """An aided mode chooses its own solvers and fine stage: a fixed-base option given with it would be ignored."""
    given = [flag for name, flag in FIXED_BASE_OPTIONS.items() if getattr(args, name, None) is not None]
    if aided and given:
        from sinsalign.service.config import ConfigError
        raise ConfigError(f"{', '.join(given)} set the fixed-base alignment; an aided mode chooses its own solvers "
                          "(the odometer's: [aiding] solver) and has no compass stage")


def cmd_sim(args: argparse.Namespace) -> int:
    from sinsalign.tools.sim.files import write_simulation
    from sinsalign.tools.sim.scenarios import SCENARIOS, seed_run
    if args.list or not args.scenario:
        for name, s in SCENARIOS.items():
            print(f"{name:22s} {s.description}")
        print("\nEach name also runs without sensor errors as NAME-ideal.")
        return 0
    scenario = seed_run(args.scenario, args.seed, args.duration)
    files = write_simulation(scenario, args.seed, args.out_dir, binary=args.binary)
    aids = "".join(f" and {path}" for path in (files.odo_csv, files.gnss_csv, files.master_csv) if path)
    print(f"wrote {files.imu_csv}, {files.truth_csv}{aids} ({scenario.duration_s:g} s at {scenario.rate_hz:g} Hz)")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from sinsalign.service.config import load_config
    from sinsalign.tools.replay import parse_aids, replay
    _refuse_fixed_base_options(args, bool(args.aid))
    config = load_config(args.config, _overrides(args))
    start = time.perf_counter()
    summary = replay(args.imu_csv, args.out, config, progress=None if not args.no_progress else False,
                     aids=parse_aids(args.aid))
    elapsed = time.perf_counter() - start
    last = summary.last
    print(f"{summary.samples} samples → {summary.records} results in {args.out} "
          f"({summary.samples / max(elapsed, 1e-9):,.0f} frames/s; {summary.stages})", file=sys.stderr)
    if last is not None:
        print(f"t = {last.t:g} s: heading {last.heading_deg:.4f}° ± {last.heading_sigma_deg:.4f}°, "
              f"pitch {last.pitch_deg:.4f}°, roll {last.roll_deg:.4f}° (level σ {last.level_sigma_deg:.4f}°), "
              f"phase {last.phase}, converged: {last.converged}", file=sys.stderr)
    if summary.gate:
        print("sample gate: " + ", ".join(f"{name} {value}" for name, value in summary.gate.items()), file=sys.stderr)
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    from sinsalign.tools.convert import convert
    samples = convert(args.source, args.target)
    print(f"{samples} samples: {args.source} → {args.target}", file=sys.stderr)
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    from sinsalign.service.config import load_config
    from sinsalign.tools.eval_command import run_eval
    overrides = _overrides(args)
    config = load_config(args.config, overrides)   # a wrong file or option fails here, before any run
    run_eval(args.argv, args.scenario, range(args.first_seed, args.first_seed + args.seeds * args.seed_sets),
             args.seeds, Path(args.out_dir), config, bool(args.config or overrides), args.budget, args.fine,
             args.solvers)
    return 0


def cmd_benchmark(args: argparse.Namespace) -> int:
    from sinsalign.tools.benchmark import report
    from sinsalign.tools.stamp import stamp
    print(stamp(args.argv) + "\n\n" + report(args.seconds, args.repeat, args.live, args.live_seconds,
                                             args.stream_hours, args.long_seconds))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from sinsalign.tools.demo import run_demo, summary
    speed = 1.0 if args.realtime else args.speed
    print(f"live bench: virtual IMU ({args.scenario}, seed {args.seed}) → pty → daemon → Zenoh (peer, loopback) "
          f"→ watch, at ×{speed:g} real time", file=sys.stderr)
    result = run_demo(args.scenario, args.seed, speed, Path(args.out_dir), show=not args.no_watch,
                      duration_s=args.duration)
    print("\n" + summary(result, args.scenario))
    return 0


def _zenoh_overrides(args: argparse.Namespace) -> dict:
    z = {k: v for k, v in (("mode", args.mode), ("connect", args.connect), ("listen", args.listen),
                           ("config_file", args.zenoh_config), ("unit", args.unit), ("prefix", args.prefix))
         if v is not None}
    return {"zenoh": z} if z else {}


def _add_zenoh_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("Zenoh (defaults: peer on loopback tcp/127.0.0.1:7447, multicast scouting off)")
    g.add_argument("-m", "--mode", choices=("peer", "client", "router"), help="Zenoh connection mode")
    g.add_argument("-e", "--connect", action="append", metavar="ENDPOINT", help="endpoint to connect to, e.g. "
                   "tcp/10.0.0.5:7447 (repeatable)")
    g.add_argument("-l", "--listen", action="append", metavar="ENDPOINT", help="endpoint to listen on (repeatable)")
    g.add_argument("--zenoh-config", metavar="FILE", help="a standard Zenoh JSON5 configuration as the base")
    g.add_argument("--unit", help="unit id in the keys <prefix>/<unit>/… (default unit1)")
    g.add_argument("--prefix", help="key prefix (default sinsalign)")


def cmd_serve(args: argparse.Namespace) -> int:
    import gc
    import logging
    import signal

    from sinsalign.service.config import ConfigError, load_config
    from sinsalign.service.daemon import Daemon
    from sinsalign.service.realtime import request_realtime
    from sinsalign.service.serial_port import SerialPort
    from sinsalign.service.zenoh_session import open_session
    overrides = {**_overrides(args), **_zenoh_overrides(args)}
    serial_table = {k: v for k, v in (("path", args.serial), ("baud", args.baud)) if v is not None}
    if serial_table:
        overrides["serial"] = serial_table
    if args.zenoh_imu:
        overrides.setdefault("zenoh", {})["imu_input"] = True
    if args.record:
        overrides["daemon"] = {"record_path": args.record}
    if args.aid:
        overrides["aiding"] = {"inputs": args.aid}
    if args.imu_format:
        overrides["imu"] = {"format": args.imu_format}
    if args.nmea_udp:
        overrides["nmea"] = {"udp": args.nmea_udp}
    if args.ros2:
        overrides["ros2"] = {"enabled": True}
    _refuse_fixed_base_options(args, bool(args.aid))
    config = load_config(args.config, overrides)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)
    if not config.serial.path and not config.zenoh.imu_input:
        raise ConfigError("no input: give --serial PATH (serial.path) or --zenoh-imu (zenoh.imu_input = true)")
    port = SerialPort(config.serial.path, config.serial.baud, config.serial.reconnect_max_s) \
        if config.serial.path else None
    request_realtime(config.daemon.realtime_priority)   # before the session: its threads inherit it
    try:
        with open_session(config.zenoh) as session:   # closed however the daemon ends, or fails to start
            daemon = Daemon(config, session, port)
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda *_: daemon.stop())
            # what start-up built lives as long as the process: kept out of the collector's full passes, which
            # otherwise walk all of it now and then and hold a sample's attitude back by up to 10 ms
            gc.collect()
            gc.freeze()
            daemon.run()
    finally:
        if port is not None:
            port.close()
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from sinsalign.service.config import load_config
    from sinsalign.tools.bench_command import run_bench
    config = load_config(args.config, {"imu": {"format": args.imu_format}})
    return run_bench(args.log, args.scenario, args.seed, args.duration, args.aid, args.aid_late, args.port,
                     args.speed, args.start_delay, config.imu, args.aid_format, args.aid_port)


def cmd_fuzz(args: argparse.Namespace) -> int:
    from sinsalign.tools.fuzz import fault_table, progress_bar, run_all
    from sinsalign.tools.stamp import stamp
    provenance = stamp(args.argv)   # the commit the run starts on
    with progress_bar(sys.stderr.isatty() and not args.no_progress) as progress:
        tallies = run_all(args.inputs, args.values, args.seed, progress)
    table = fault_table(tallies, provenance, args.seed)
    print(table)
    if args.out:
        Path(args.out).write_text(table + "\n")
    for tally in tallies:
        if tally.first_escape:
            print(f"first escape of {tally.first_escape}", file=sys.stderr)
    return 1 if any(tally.escaped for tally in tallies) else 0


def cmd_soak(args: argparse.Namespace) -> int:
    import numpy as np

    from sinsalign.service.config import ConfigError, config_from_mapping
    from sinsalign.tools.soak import percentiles_ms, soak
    if args.report_every > 3600.0 * args.hours:
        raise ConfigError(f"--hours {args.hours:g} must hold at least one --report-every interval "
                          f"({args.report_every:g} s of data)")
    if args.window >= args.report_every:
        raise ConfigError(f"--window {args.window:g} must be shorter than --report-every {args.report_every:g}")
    config_from_mapping({"daemon": {"realtime_priority": args.realtime_priority}})   # the key's own bounds
    through = "the null relay (no alignment: the floor)" if args.floor else "'sinsalign serve'"
    if args.realtime_priority:
        through += f" under SCHED_FIFO {args.realtime_priority}"
    print(f"soak: {args.hours:g} h of 200-Hz frames through {through} on a pty, attitude for every sample: "
          f"flat out, the last {args.window:g} s of every {args.report_every:g} s at 200 Hz", file=sys.stderr)

    def own(reports: list) -> str:
        """The daemon's own figures over ``reports`` (the worst of each), none for the null relay."""
        if args.floor:
            return ""
        return (f"; the daemon's own (read → published) p99 {max(r.own_p99_ms for r in reports):.2f} ms, max "
                f"{max(r.own_max_ms for r in reports):.2f} ms (CPU {max(r.own_max_cpu_ms for r in reports):.2f} ms)")

    def show(s) -> None:
        p50, p99, most = percentiles_ms(s.latency_ms)
        print(f"  {s.hours:7.2f} h simulated, {s.wall_s:6.0f} s wall: RSS {s.rss_mib:6.2f} MiB, frame → attitude "
              f"p50 {p50:5.2f} ms p99 {p99:5.2f} ms max {most:6.2f} ms ({s.received}/{s.frames}){own([s])}", flush=True)

    samples = soak(args.hours, args.report_every, args.window, on_sample=show, floor=args.floor,
                   realtime_priority=args.realtime_priority)
    p50, p99, most = percentiles_ms(np.concatenate([s.latency_ms for s in samples]))
    print(f"RSS growth from the first report to the last: {samples[-1].rss_mib - samples[0].rss_mib:+.2f} MiB; "
          f"frame → attitude over every window: p50 {p50:.2f} ms, p99 {p99:.2f} ms, max {most:.2f} ms "
          f"({sum(s.received for s in samples)}/{sum(s.frames for s in samples)} received){own(samples)}")
    return 0


def cmd_config(args: argparse.Namespace) -> int:
    from sinsalign.service.config import config_toml, load_config
    print(config_toml(load_config(args.config)), end="")
    return 0


def cmd_reference(args: argparse.Namespace) -> int:
    from sinsalign.tools.reference import SECTIONS, reference
    print("\n".join(reference(section) for section in ([args.section] if args.section else SECTIONS)), end="")
    return 0


def cmd_watch(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from sinsalign.protocol.keys import UnitKeys
    from sinsalign.service.config import load_config
    from sinsalign.service.zenoh_session import open_session
    from sinsalign.tools.watch import WatchClient, watch
    config = load_config(args.config, _zenoh_overrides(args))
    z = config.zenoh
    if not (z.connect or z.listen or z.config_file):   # neither options nor file say: the local daemon
        config = replace(config, zenoh=replace(z, connect=("tcp/127.0.0.1:7447",)))
    with open_session(config.zenoh) as session:
        client = WatchClient(session, UnitKeys(config.zenoh.prefix, config.zenoh.unit),
                             only_unit=args.unit is not None)
        try:
            watch(client, args.duration)
        except KeyboardInterrupt:
            pass
        finally:
            client.close()
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
    p.add_argument("--seed", type=SEED, default=1, help="noise seed (default 1)")
    p.add_argument("--duration", type=POSITIVE, metavar="S", help="override the scenario's duration")
    p.add_argument("--out-dir", default="out/sim", help="output folder (default out/sim)")
    p.add_argument("--list", action="store_true", help="list the scenarios")
    p.add_argument("--binary", action="store_true", help="write the IMU log in its binary form (imu.sbin: "
                   "docs/reference.md, 'Binary IMU log'), for long runs")
    p.set_defaults(func=cmd_sim)

    p = sub.add_parser("replay", help="align a recorded IMU log as fast as possible → JSON Lines",
                       description="Process IMU.csv (pinned log format) and write one JSON object per output epoch "
                       "(t on whole multiples of the output period) with q, Euler angles, heading/level σ, "
                       "phase and converged. A malformed log stops with the file, line and column named.")
    p.add_argument("imu_csv", metavar="IMU.csv", help="the IMU log (pinned CSV, docs/reference.md 'IMU log "
                   "format', or its binary form, 'Binary IMU log')")
    p.add_argument("--out", required=True, metavar="RESULTS.jsonl",
                   help="the results, one JSON object per output epoch")
    p.add_argument("--period", type=float, metavar="S", help="output period (default 1 s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--aid", action="append", metavar="KIND=FILE",
                   help="an aiding log (pinned format, same time base); the kinds given select the mode: "
                   "odo=ODO.csv in-motion alignment with odometer/DVL body velocity (multistage coarse window, then "
                   "a Kalman stage), gnss=GNSS.csv in-flight alignment with GNSS fixes (antenna lever arm from the "
                   "log's lever_*_m keys), both together a land vehicle with both sensors, master=MASTER.csv "
                   "transfer alignment against a master INS; repeat --aid for each log")
    _add_alignment_options(p)
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("convert", help="an IMU log from CSV to its binary form (.sbin) or back",
                       description="Copy an IMU log between the pinned CSV and its binary form (docs/reference.md, "
                       "'Binary IMU log'): every sample exact, the daemon's restart marks kept. The source's form is "
                       "told by its first line, the target's by its name (.sbin: binary). The binary form reads "
                       "many times faster; replay takes either, and so does the daemon's --record.")
    p.add_argument("source", metavar="IN", help="an IMU log, CSV or binary")
    p.add_argument("target", metavar="OUT", help="the copy (.sbin: binary, else CSV; owner-only)")
    p.set_defaults(func=cmd_convert)

    p = sub.add_parser("eval", help="Monte Carlo against simulated truth: table, settling, σ honesty, plot",
                       description="Run N seeds of a scenario in memory; print a paper-style table of heading and "
                       "level errors relative to each run's physical limit, settling time and how honest σ is; "
                       "save OUT_DIR/SCENARIO_heading.png and OUT_DIR/SCENARIO.md. --config FILE and the alignment "
                       "options configure the scenario's run (the scenario sets the site, rate and datasheet); the "
                       "--solvers and --fine comparisons and the aided tables run their own fixed variants.")
    p.add_argument("scenario", help="a scenario name (sinsalign sim --list), or seed003 for the in-motion table over "
                   "20/60/80 m/s (traditional V^b vs multistage at 120 s, then the Kalman stage to 600 s), or "
                   "seed002 for the transfer-alignment table (dual model vs phase 1 alone, master faults; then phase 1 "
                   "against the seed's additive-quaternion EKF), or "
                   "seed004 for the in-flight GNSS table (VIF vs PIF, lever arm compensated or ignored, and VIF "
                   "through glitches and a 20-s outage; heading at 10/60/300 s, σ honesty), or seed004-rates for "
                   "the same flight with 50/10/5/1-Hz receivers (120 s: accuracy, σ honesty, gaps), or "
                   "seed002-rates for the transfer alignment with the master INS at 10/5/2/1 Hz, or honesty for "
                   "the honesty sweep (every mode on its motion × navigation/tactical/MEMS IMU × datasheet stated "
                   "or understated 10×: converged records beyond 3σ and records within 2σ per cell)")
    p.add_argument("--seeds", type=POSITIVE_INT, default=20, help="number of seeds (default 20)")
    p.add_argument("--first-seed", type=SEED, default=0, help="the first seed (default 0; the others follow it)")
    p.add_argument("--seed-sets", type=POSITIVE_INT, default=1, metavar="K",
                   help="run K disjoint sets of --seeds seeds and add a table of the last window per set (how much a "
                   "20-seed figure moves with the seeds; the docs' tables: --seeds 20 --seed-sets 5)")
    p.add_argument("--solvers", action="store_true", help="also compare OPREQ, q-method and REQUEST gains")
    p.add_argument("--budget", action="store_true", help="also run the same seeds with each IMU error alone (biases "
                   "and other systematic errors, accelerometer noise, gyro noise; the datasheet unchanged) and print "
                   "the last window's error budget: which error the heading's figures come from")
    p.add_argument("--fine", action="store_true", help="also run seed 001's comparison: OPREQ only, compass alone "
                   "from 1.5°, OPREQ → compass, each with and without stored data; table and plot")
    p.add_argument("--out-dir", default="out/eval", help="where the Markdown table and its plot go (default out/eval)")
    _add_alignment_options(p)
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser("benchmark", help="benchmarks: replay frames/s, per-sample latency, RSS over a long stream",
                       description="Numbers, not pass/fail. --stream-hours 24 streams a day of 200-Hz data "
                       "generated on the fly and reports RSS every simulated hour.")
    p.add_argument("--seconds", type=POSITIVE, default=600.0, help="length of the replayed log (default 600 s)")
    p.add_argument("--long-seconds", type=POSITIVE, default=3600.0, help="length of the long log (default 3600 s)")
    p.add_argument("--repeat", type=POSITIVE_INT, default=5, help="replays per configuration; best and median are "
                   "reported (a shared machine's speed varies from run to run; default 5)")
    p.add_argument("--stream-hours", type=NON_NEGATIVE, default=0.0, help="hours of streamed data (0 = skip; try 24)")
    p.add_argument("--live", action="store_true", help="also the live daemon: latency frame → attitude, CPU, ingest")
    p.add_argument("--live-seconds", type=POSITIVE, default=20.0, help="seconds of 200-Hz frames for --live")
    p.set_defaults(func=cmd_benchmark)

    p = sub.add_parser("serve", help="run the daemon: serial and/or Zenoh IMU in, attitude and status out",
                       description="Read IMU frames from a serial port (RS-422 adapter or a bench pty) and/or the "
                       "Zenoh key <prefix>/<unit>/imu, align, and publish <prefix>/<unit>/attitude (msgpack, every "
                       "output epoch) and <prefix>/<unit>/status (1 Hz, counters and health); hold the liveliness "
                       "token <prefix>/<unit>/alive and answer <prefix>/<unit>/state. With --aid KIND, aiding epochs "
                       "come from <prefix>/<unit>/aid/KIND and serial aiding frames, and each IMU sample waits for "
                       "its aiding (its interval plus aiding.max_wait_s). Stops cleanly on SIGINT or SIGTERM. "
                       "Example: sinsalign serve "
                       "--serial /dev/ttyUSB0 --baud 921600 --config bench.toml [--aid gnss]")
    p.add_argument("--serial", metavar="PATH", help="serial device, e.g. /dev/ttyUSB0 or a pty from sinsalign bench")
    p.add_argument("--baud", type=int, help="baud rate (default 921600; a pty ignores it)")
    p.add_argument("--zenoh-imu", action="store_true", help="also take IMU samples from <prefix>/<unit>/imu")
    p.add_argument("--imu-format", choices=IMU_FORMATS, help="the IMU's serial frame (imu.format; default "
                   "sinsalign, the project's frame; a vendor's is stamped from its counter, axes from imu.axes)")
    p.add_argument("--nmea-udp", action="append", metavar="HOST:PORT", help="send NMEA 0183 heading sentences "
                   "(THS, ROT, PASHR by default; [nmea] table) as UDP datagrams here (repeatable)")
    p.add_argument("--ros2", action="store_true", help="publish sensor_msgs/msg/Imu (CDR) on "
                   "<prefix>/<unit>/ros/imu for zenoh-bridge-ros2dds (needs the ros2 extra)")
    p.add_argument("--record", metavar="LOG", help="record the decoded input as an IMU log (owner-only file; a name "
                   "ending in .sbin: the binary form)")
    p.add_argument("--period", type=float, metavar="S", help="attitude output period (default 1 s)")
    p.add_argument("--aid", action="append", metavar="KIND",
                   help="take this aiding kind (<prefix>/<unit>/aid/KIND and serial aiding frames; aiding.inputs); "
                   "the kinds taken select the mode: odo in-motion alignment with odometer/DVL body velocity, gnss "
                   "in-flight alignment with GNSS fixes (antenna lever arm aiding.gnss.lever_m), odo and gnss "
                   "together a land vehicle with both, master transfer alignment against a master INS")
    _add_alignment_options(p)
    _add_zenoh_options(p)
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("bench", help="virtual IMU: play a scenario or a log as serial frames into a pty or a port",
                       description="Create a pseudo-terminal pair (or open --port) and write IMU frames (the "
                       "protocol/README.md frame) at ×SPEED real time. Start 'sinsalign serve --serial NAME' with "
                       "the printed NAME within --start-delay seconds.")
    p.add_argument("--scenario", default="seed000-swing", help="simulated scenario (sinsalign sim --list)")
    p.add_argument("--log", metavar="IMU.csv", help="play this IMU log instead of a scenario")
    p.add_argument("--seed", type=SEED, default=1, help="the scenario's seed (default 1: what sim, demo play too)")
    p.add_argument("--duration", type=POSITIVE, metavar="S", help="scenario length (default: the scenario's)")
    p.add_argument("--speed", type=POSITIVE, default=1.0, help="× real time (default 1)")
    p.add_argument("--port", metavar="PATH", help="write to this serial device instead of a new pty")
    p.add_argument("--start-delay", type=NON_NEGATIVE, default=3.0, metavar="S",
                   help="wait before playing (default 3 s)")
    p.add_argument("--aid", action="store_true", help="also play the scenario's aiding sensors (odometer of "
                   "seed003-*, GNSS of seed004, both of seed003-odo-gnss, master INS of seed002) as serial aiding "
                   "frames among the IMU frames; serve with the [aiding] table printed")
    p.add_argument("--aid-late", type=NON_NEGATIVE, default=0.2, metavar="S",
                   help="how far behind the IMU frames the aiding epochs come (s of data, default 0.2)")
    p.add_argument("--aid-format", choices=GNSS_INPUTS, default="sinsalign", help="the GNSS receiver's output: "
                   "serial aiding frames on the IMU's line (default), or NMEA 0183 (GGA, RMC, VTG) or UBX NAV-PVT "
                   "on a pty of its own (its name printed; serve with [aiding.gnss] input and serial)")
    p.add_argument("--aid-port", metavar="PATH", help="with --aid-format nmea or ubx: write the receiver's output to "
                   "this serial device instead of a new pty")
    p.add_argument("--imu-format", choices=IMU_FORMATS, default="sinsalign", help="emulate this IMU's frames "
                   "(default sinsalign; a vendor's take their settings, axes and rate from --config)")
    p.add_argument("--config", metavar="TOML", help="the daemon's configuration: [imu] axes and the vendor's table")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("fuzz", help="hostile input into every input class; a Markdown fault table",
                       description="Feed random and absurd input into every input class: serial bytes, Zenoh "
                       "msgpack messages, the sample gate and pipeline (the daemon's ingest), aiding epochs, the "
                       "replay of IMU and aiding logs, the configuration (mappings and TOML files). Prints a "
                       "Markdown table (stamped with the command and commit) of what was accepted, dropped and "
                       "counted, refused with the documented error, or escaped (any other exception); exit 1 if "
                       "anything escaped, its input and traceback on stderr.")
    p.add_argument("--inputs", type=POSITIVE_INT, default=1_000_000, metavar="N",
                   help="random pieces into the serial decoder; a fifth as many msgpack messages and aiding epochs "
                   "(default 1000000)")
    p.add_argument("--values", type=POSITIVE_INT, default=4_000_000, metavar="N",
                   help="values generated for the sample stream (35 %%), the replayed logs (45 %%) and the "
                   "configuration (20 %%) (default 4000000)")
    p.add_argument("--seed", type=SEED, default=0, help="random seed of the generated input (default 0)")
    p.add_argument("--out", metavar="FILE", help="also write the table to FILE")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (default: on a terminal)")
    p.set_defaults(func=cmd_fuzz)

    p = sub.add_parser("soak", help="hours of simulated data through the live daemon: RSS and latency over time",
                       description="Run 'sinsalign serve' in its own process on a pty, publishing attitude for every "
                       "sample, and write HOURS of 200-Hz frames (static base with noise, generated on the fly): each "
                       "REPORT_EVERY simulated seconds flat out (as fast as the daemon reads them) but for the last "
                       "WINDOW seconds, which go at 200 Hz one frame at a time. Every report gives the daemon's RSS "
                       "and the frame → attitude latency of the window's frames, as a subscriber sees it, and the "
                       "daemon's own share of it (read → published, from its statuses' loop figures: the rest is the "
                       "machine's wake-ups and Zenoh); the end, the RSS growth after the first report and the latency "
                       "over every window. 24 h take about 13 min.")
    p.add_argument("--hours", type=POSITIVE, default=24.0, help="hours of simulated data (default 24)")
    p.add_argument("--report-every", type=POSITIVE, default=3600.0, metavar="S",
                   help="simulated seconds per report (default 3600)")
    p.add_argument("--window", type=POSITIVE, default=10.0, metavar="S",
                   help="seconds at the end of each report played at 200 Hz for the latency (default 10)")
    p.add_argument("--floor", action="store_true",
                   help="the same through a null relay instead of the daemon (the same serial read, frame decoder "
                   "and attitude messages, no alignment): this machine's floor of the frame → attitude latency")
    p.add_argument("--realtime-priority", type=SEED, default=0, metavar="N",
                   help="the daemon's (or relay's) daemon.realtime_priority: SCHED_FIFO at N (1-99) if the system "
                   "grants it (default 0: the normal scheduler; the soak itself keeps its own)")
    p.set_defaults(func=cmd_soak)

    p = sub.add_parser("config", help="print the configuration in effect as TOML",
                       description="Print every key with its value after the defaults and --config FILE (validated: "
                       "a wrong key or value is the same one-line error as at a start), as a TOML file --config "
                       "takes back. Every key's meaning and bounds: sinsalign reference config.")
    p.add_argument("--config", metavar="FILE", help="TOML configuration to validate and show")
    p.set_defaults(func=cmd_config)

    p = sub.add_parser("reference", help="print the reference of the command line, the configuration or the counters",
                       description="Print, as Markdown, the generated parts of docs/reference.md: every subcommand "
                       "and option (cli), every configuration key with its default, bounds and meaning (config), "
                       "every status counter with what it counts and whether a rise is a fault (counters).")
    p.add_argument("section", nargs="?", choices=("cli", "config", "counters"), help="one section (default: all)")
    p.set_defaults(func=cmd_reference)

    p = sub.add_parser("watch", help="live terminal view of every unit: attitude, σ, phase, counters",
                       description="Subscribe to <prefix>/*/attitude and status (with --unit: that unit's) and "
                       "show them live. Connects to tcp/127.0.0.1:7447 unless -e/-l/--zenoh-config or the "
                       "--config file's [zenoh] table say otherwise.")
    p.add_argument("--duration", type=POSITIVE, metavar="S", help="stop after S seconds (default: Ctrl-C)")
    p.add_argument("--config", metavar="FILE", help="TOML configuration ([zenoh] table)")
    _add_zenoh_options(p)
    p.set_defaults(func=cmd_watch)

    p = sub.add_parser("demo", help="the main job: live bench (virtual IMU → pty → daemon → Zenoh → watch)",
                       description="Play a simulated scenario as serial frames into a pty, run the daemon on it "
                       "(Zenoh peer on loopback, multicast off), watch it live, and end with the heading error "
                       "against the simulated truth and the run's physical limit.")
    p.add_argument("--scenario", default="seed000-swing",
                   help="scenario to play (sinsalign sim --list; default seed000-swing)")
    p.add_argument("--seed", type=SEED, default=1, help="its seed (default 1)")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--speed", type=POSITIVE, default=10.0, help="× real time (default 10: 200 s in 20 s)")
    pace.add_argument("--realtime", action="store_true", help="play at real time (same as --speed 1)")
    p.add_argument("--duration", type=POSITIVE, metavar="S", help="scenario length (default: the scenario's)")
    p.add_argument("--no-watch", action="store_true", help="no live view, summary only")
    p.add_argument("--out-dir", default="out/demo", help="the daemon's recording of its input goes here")
    p.set_defaults(func=cmd_demo)
    return parser


def _check_scenario(args: argparse.Namespace) -> None:
    """A scenario name the simulator does not know is the user's error, said before anything runs (``main`` lets
    a KeyError through: anywhere else it is a bug, and shows as one)."""
    name = getattr(args, "scenario", None)
    if not name:
        return   # before the imports: the simulator's modules are no part of a replay
    from sinsalign.service.config import ConfigError
    from sinsalign.tools.eval_command import AIDED_TABLES
    from sinsalign.tools.sim.scenarios import get_scenario
    if name in AIDED_TABLES:
        return
    try:
        get_scenario(name)
    except KeyError as exc:
        raise ConfigError(exc.args[0]) from None


def _user_errors() -> tuple[type[BaseException], ...]:
    """The errors a command reports in one line (exit 2): a bad log, configuration or file, and a Zenoh session's
    (only a command that opened one can raise it: Zenoh is not imported for the others)."""
    from sinsalign.protocol.imu_log import LogFormatError
    from sinsalign.service.config import ConfigError
    zenoh = sys.modules.get("zenoh")
    return (LogFormatError, ConfigError, OSError) + ((zenoh.ZError,) if zenoh is not None else ())


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = sys.argv[1:] if argv is None else list(argv)   # the command line a generated table is stamped with
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        _check_scenario(args)
        return args.func(args)
    except KeyboardInterrupt:
        return 130
    except Exception as exc:
        if not isinstance(exc, _user_errors()):
            raise
        print(f"sinsalign {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
