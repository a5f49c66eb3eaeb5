"""The generated parts of docs/reference.md: the command line (from the argument parser), the configuration (from
its fields, :func:`~sinsalign.service.config.reference_markdown`) and the status counters (from the counter
classes). ``sinsalign reference`` prints them; a test checks that the document holds exactly these."""
from __future__ import annotations

import argparse

from sinsalign.protocol import messages
from sinsalign.protocol.aiding_log import KINDS
from sinsalign.protocol.declared_frame import FrameCounters
from sinsalign.protocol.gnss_fix import ReceiverCounters
from sinsalign.protocol.kvh import KvhCounters
from sinsalign.protocol.sequence import SEQUENCE_DOCS
from sinsalign.protocol.serial_frame import DecoderCounters
from sinsalign.protocol.stim300 import Stim300Counters
from sinsalign.protocol.xsens import XsensCounters
from sinsalign.service.aiding import AidingCounters
from sinsalign.service.config import reference_markdown
from sinsalign.service.gnss_receiver import ReceiverInputCounters
from sinsalign.service.ingest import SampleCounters
from sinsalign.service.nmea_outputs import NmeaCounters
from sinsalign.service.sample_gate import GateCounters

SECTIONS = ("cli", "config", "counters")

MEASUREMENTS = {"odo": "odometer body velocity", "gnss_vel": "GNSS velocity", "gnss_pos": "GNSS position",
                "master_vel": "master velocity", "master_att": "master attitude"}
"""The Kalman filter's measurements, by the name their counters carry."""

ESTIMATOR_DOCS = {
    **{f"{kind}_observations_awaiting_aid": f"coarse observations due before the {kind} stream's first usable value "
       "(a wait, not a fault)" for kind in KINDS},
    **{f"{kind}_unaided_observations": f"coarse observations due without {kind} values after the stream began (a "
       "dropout)" for kind in KINDS},
    **{f"{name}_accepted": f"{what} updates the filter took" for name, what in MEASUREMENTS.items()},
    **{f"{name}_rejected": f"{what} updates the χ² gate turned away" for name, what in MEASUREMENTS.items()},
    "odo_outlier_pairs": "multistage window pairs left out as outliers (a wheel slip)",
    "gnss_coarse_rejected": "coarse pairs the fit's screen left out (a glitch of the fixes)",
    "gnss_coarse_reopened": "screens reopened after a run of rejections (a lasting change of the data)",
    "estimator_restarts": "steps that raised or put out a non-finite number: the alignment started over",
    "disturbances": "episodes of a fixed base that moved, and estimates that contradicted their σ (a restart)",
}
"""The estimators' and the restarting pipeline's counters."""

DAEMON_DOCS = {
    "serial_disconnects": "read errors of the serial port (it vanished)",
    "serial_reconnects": "the serial port reopened after a disconnect",
    "serial_foreign_devices": "the serial path came back as another device: not opened",
    "oversized_messages": "Zenoh payloads larger than any valid message, refused in the callback",
    "gnss_serial_disconnects": "read errors of the GNSS receiver's own port ([aiding.gnss] serial)",
    "gnss_serial_reconnects": "the GNSS receiver's port reopened after a disconnect",
    "gnss_serial_foreign_devices": "the GNSS receiver's path came back as another device: not opened",
}


def counter_docs() -> dict[str, str]:
    """Every status counter, by name, with what it counts (a name the project's frame and a vendor's share: as the
    project's frame counts it)."""
    vendor = {**Stim300Counters.docs(), **KvhCounters.docs(), **XsensCounters.docs(), **FrameCounters.docs()}
    return {**vendor, **DecoderCounters.docs(), **{f"seq_{k}": v for k, v in SEQUENCE_DOCS.items()},
            **{f"aiding_seq_{k}": v for k, v in SEQUENCE_DOCS.items()},
            **{f"zenoh_seq_{k}": v for k, v in SEQUENCE_DOCS.items()}, **SampleCounters.docs(),
            **GateCounters.docs(), **{f"<kind>_{k}": v for k, v in AidingCounters.docs().items()},
            **ReceiverCounters.docs("gnss_rx_"), **ReceiverInputCounters.docs("gnss_rx_"),
            **NmeaCounters.docs(), **ESTIMATOR_DOCS, **DAEMON_DOCS}


def _class_of(name: str) -> str:
    """What a counter is to the status's health: work, a screen's rejections, or a fault."""
    example = name.replace("<kind>", "gnss")
    if example in messages.NOT_FAULTS:
        return "work"
    return "screened" if example in messages.SCREENED else "fault"


def counters_markdown() -> str:
    """The status counters' reference: name, what it counts, and whether a rise is a fault (health ``degraded``)."""
    lines = ["| counter | counts | a rise is |", "|---|---|---|"]
    lines += [f"| `{name}` | {doc} | {_class_of(name)} |" for name, doc in counter_docs().items()]
    return "\n".join(lines) + "\n\n`<kind>` is `odo`, `gnss` or `master`: one set per aiding stream the mode takes.\n"


def _option(action: argparse.Action) -> str:
    flags = ", ".join(f"`{f}`" for f in action.option_strings) or f"`{action.metavar or action.dest}`"
    if action.choices and not isinstance(action.choices, dict):
        flags += " {" + ", ".join(str(c) for c in action.choices) + "}"
    elif action.nargs != 0 and action.option_strings:
        flags += f" {action.metavar or action.dest.upper()}"
    return flags


def cli_markdown(parser: argparse.ArgumentParser) -> str:
    """Every subcommand of ``parser`` with its purpose and options, as its ``--help`` states them."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {choice.dest: choice.help for choice in sub._choices_actions}
    out = []
    for name, command in sub.choices.items():
        out += [f"**`sinsalign {name}`**: {helps.get(name, '')}.", "", "| option | meaning |", "|---|---|"]
        out += [f"| {_option(a)} | {' '.join((a.help or '').split()).replace('|', '/')} |" for a in command._actions
                if not isinstance(a, argparse._HelpAction)]
        out.append("")
    return "\n".join(out)


def reference(section: str) -> str:
    """One generated section of docs/reference.md (:data:`SECTIONS`)."""
    if section == "config":
        return reference_markdown()
    if section == "counters":
        return counters_markdown()
    from sinsalign.cli import build_parser
    return cli_markdown(build_parser())
