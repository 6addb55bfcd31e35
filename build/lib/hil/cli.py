"""``zarco hil``: registered through the ``zarco.commands`` entry point."""

from __future__ import annotations

import argparse


def _positive(text: str) -> float:
    v = float(text)
    if not v >= 0.0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 0, got {text}")
    return v


def cmd_hil(args: argparse.Namespace) -> int:
    from hil.run import main_hil

    return main_hil(args)


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add this package's sub-commands to the ``zarco`` parser."""
    h = sub.add_parser(
        "hil", help="hardware-in-the-loop: zarco run against a simulator behind pseudo-terminals",
        description="Run a scenario in real time: the simulator serves one pseudo-terminal "
                    "per device (GPS, compass, thrusters, and the LBL buoy's feed when the "
                    "scenario follows the AUV) behind stable links in a run directory, "
                    "`zarco run` reads them as serial ports in its own process and reports "
                    "through its --status file, the loop closes through the thruster port; "
                    "faults from the scenario's [[faults]] are injected at their times. "
                    "Writes the report and plot of `zarco sim`.")
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
