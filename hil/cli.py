"""Sub-commands of ``zarco`` that live with the HIL tools (hil, replay, decode)."""

from __future__ import annotations

import argparse


def _positive(text: str) -> float:
    v = float(text)
    if not v >= 0.0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 0, got {text}")
    return v


def cmd_decode(args: argparse.Namespace) -> int:
    from zarco_runtime.decode import main_decode

    return main_decode(args.log, args.variation, args.summary)


def cmd_replay(args: argparse.Namespace) -> int:
    from zarco_runtime.replay import main_replay

    return main_replay(args)


def cmd_hil(args: argparse.Namespace) -> int:
    from hil.run import main_hil

    return main_hil(args)


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add this package's sub-commands to the ``zarco`` parser."""
    d = sub.add_parser(
        "decode", help="print what the drivers accept in an NMEA capture, one JSON line each",
        description="Decode an NMEA capture the way the drivers do: one JSON line per "
                    "accepted sentence on stdout, refusals with their reason on stderr. "
                    "Lines starting with # are skipped.")
    d.add_argument("log", help="capture file, or - for standard input")
    d.add_argument("--variation", type=float, default=None, metavar="DEG",
                   help="magnetic variation (east +) for sentences that carry none "
                        "(HDM, VTG magnetic track)")
    d.add_argument("-s", "--summary", action="store_true",
                   help="print counts of accepted and refused sentences on stderr at the end")
    d.set_defaults(func=cmd_decode)

    r = sub.add_parser(
        "replay", help="feed a recorded NMEA capture into a serial port at its recorded pace",
        description="Write a capture into a serial port (or pseudo-terminal) at the pace "
                    "of its ZDA/RMC/GGA times, or N times faster. Lines starting with # are "
                    "not sent.")
    r.add_argument("log", help="capture file, or - for standard input")
    r.add_argument("--port", required=True, metavar="PATH",
                   help="serial port or pseudo-terminal to write to")
    r.add_argument("--rate", type=_positive, default=1.0, metavar="N",
                   help="play N times faster than recorded (0: as fast as the port takes)")
    r.add_argument("--baudrate", type=int, default=115200, help="serial speed (bit/s)")
    r.add_argument("--line-rate", type=_positive, default=10.0, metavar="HZ",
                   help="lines per second when the capture carries no times (default 10)")
    r.add_argument("--max-gap", type=_positive, default=10.0, metavar="S",
                   help="shorten longer silences in the capture to this (s, recorded time; "
                        "default 10; 0: keep every gap)")
    r.add_argument("--loop", type=int, default=1, metavar="K",
                   help="play the capture K times (0: forever)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    r.set_defaults(func=cmd_replay)

    h = sub.add_parser(
        "hil", help="hardware-in-the-loop: zarco run against a simulator behind pseudo-terminals",
        description="Run a scenario in real time: the simulator serves one pseudo-terminal "
                    "per device (GPS, compass, thrusters) behind stable links in a run "
                    "directory, `zarco run` reads them as serial ports in its own process, "
                    "the loop closes through the thruster port; faults from the scenario's "
                    "[[faults]] are injected at their times. Writes the report and plot of "
                    "`zarco sim`.")
    h.add_argument("scenario", help="scenario TOML file (with optional [[faults]])")
    h.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key by dotted path (repeatable)")
    h.add_argument("--seed", type=int, default=None, help="random seed (overrides the file)")
    h.add_argument("--report", metavar="FILE.json", help="write the JSON report here")
    h.add_argument("--plot", metavar="FILE.png", help="write the track/cross-track plot here")
    h.add_argument("--duration", type=_positive, default=None, metavar="S",
                   help="stop after S seconds of real time (default: the mission's end or "
                        "scenario.max_duration_s)")
    h.add_argument("--run-dir", metavar="DIR", default=None,
                   help="directory for the device links, runtime config and logs "
                        "(default: a new temporary directory, kept)")
    h.add_argument("--no-faults", action="store_true", help="ignore the scenario's faults")
    h.add_argument("-q", "--quiet", action="store_true", help="no running status")
    h.set_defaults(func=cmd_hil)
