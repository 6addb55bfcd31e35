"""Sub-commands of ``zarco`` for simulation and evaluation: ``sim`` (the runtime
against the simulated backend on the virtual clock), ``navreport`` (the
navigation EKF over NMEA captures), ``decode`` and ``replay`` (NMEA captures),
``log`` (recordings: info, plot, export, replay).

Registered through the ``zarco.commands`` entry point; the onboard ``zarco
run`` never loads this module.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def _fmt(v: Any, unit: str = "m") -> str:
    return f"{v:.3f} {unit}" if isinstance(v, (int, float)) else str(v)


def hold_summary(report: dict[str, Any]) -> str:
    """The station-keeping figures of a run (empty if it never held)."""
    if not report.get("holds"):
        return ""
    lines = [f"hold: distance to the point p50 {_fmt(report['hold_distance_p50_m'])}  "
             f"p95 {_fmt(report['hold_distance_p95_m'])}  "
             f"max {_fmt(report['hold_distance_max_m'])}  over {report['hold_seconds']:.0f} s; "
             f"thrust {report['hold_thrust_mean_pct']:.1f} % mean, command steps "
             f"{report['hold_command_step_rms']:.1f} % RMS"]
    for h in report["holds"]:
        lines.append(f"  at {h['t_s']:7.1f} s for {h['duration_s']:6.1f} s: p95 "
                     f"{h['distance_p95_m']:.2f} m, max {h['distance_max_m']:.2f} m "
                     f"({h['reason']})")
    return "\n".join(lines)


def summary(report: dict[str, Any]) -> str:
    """One screen of headline figures."""
    hold = hold_summary(report)
    if "xtrack_rms_m" not in report and "distance_median_m" not in report:
        head = (f"scenario {report['scenario']}  seed {report['seed']}  ({report['stop']})\n"
                f"simulated {report['sim_seconds']:.1f} s in {report['wall_seconds']:.2f} s "
                f"wall = {report['speedup']:.0f}× real time")
        return "\n".join(x for x in (head, hold) if x)
    if "xtrack_rms_m" not in report:
        from zarco_tools.follow_report import follow_summary

        return "\n".join(x for x in (follow_summary(report), hold) if x)
    lines = [
        f"scenario {report['scenario']}  seed {report['seed']}  ({report['stop']})",
        f"simulated {report['sim_seconds']:.1f} s in {report['wall_seconds']:.2f} s wall "
        f"= {report['speedup']:.0f}× real time",
        f"cross-track (≥15 m into each leg): RMS {_fmt(report['xtrack_rms_m'])}  "
        f"p95 {_fmt(report['xtrack_p95_m'])}  max {_fmt(report['xtrack_max_m'])}",
        f"corner overshoot max {_fmt(report['corner_overshoot_max_m'])} "
        f"(outside the turn {_fmt(report['corner_overshoot_outside_max_m'])})   "
        f"thrusters saturated {100 * report['saturation_fraction']:.1f} % of ticks, "
        f"command steps {report['command_step_rms']:.1f} % RMS",
        "",
        " leg  speed    RMS      p95      max    overshoot",
    ]
    for leg in report["legs"]:
        lines.append(
            f" {leg['leg']:3d}  {leg['speed_mps']:4.2f}  {_cell(leg['xtrack_rms_m'], 3)}  "
            f"{_cell(leg['xtrack_p95_m'], 3)}  {_cell(leg['xtrack_max_m'], 3)}  "
            f"{_cell(leg['overshoot_m'], 2)}"
        )
    if report.get("faults"):
        lines.append("")
        lines.append("faults: " + "; ".join(report["faults"]))
    return "\n".join(lines)


def _cell(v: float | None, digits: int) -> str:
    """A table cell 7 wide: the value, or "—" where a leg has none (a run cut short)."""
    return f"{'—':>7}" if v is None else f"{v:7.{digits}f}"


def cmd_sim(args: argparse.Namespace) -> int:
    from zarco_tools.run_outputs import RunOutputs
    from zarco_tools.scenario import load_scenario
    from zarco_tools.simulation import StatusLine, run_scenario

    scn = load_scenario(args.scenario, args.set, args.seed)
    out = RunOutputs.check(args.report, args.plot, args.record)  # before the run
    status = None if args.quiet else StatusLine()
    try:
        if args.realtime:
            print(f"zarco sim: {scn.scenario.name} running in real time (links as configured); "
                  "SIGTERM or Ctrl-C ends it", file=sys.stderr, flush=True)
        res = run_scenario(scn, progress=status, realtime=args.realtime,
                           record=str(out.record) if out.record else None)
    finally:
        if status is not None:
            status.close()
    out.write_report(res.report)

    def draw(path: Path) -> None:
        from zarco_tools.plot import plot_follow, plot_lines

        title = f"{scn.scenario.name}: seed {scn.scenario.seed}, "
        if scn.mission.kind == "follow":
            plot_follow(path, res.log, res.extra,
                        title + f"distance median {_fmt(res.report['distance_median_m'])}")
        else:
            plot_lines(path, res.log, res.legs,
                       title + f"RMS {_fmt(res.report.get('xtrack_rms_m'))}")

    out.write_plot(draw)
    out.recorded(res.extra.get("record_paths", []), res.extra.get("record_error"))
    print(summary(res.report))
    if out.written:
        print()
        print("\n".join(out.written))
    for line in out.failed:
        print(f"zarco sim: {line}", file=sys.stderr)
    return 1 if out.failed else 0


def _positive_hz(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (v > 0.0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return v


def cmd_navreport(args: argparse.Namespace) -> int:
    from zarco_tools.capture_report import main_navreport

    return main_navreport(args.logs, args.variation, args.line_rate)



def _positive(text: str) -> float:
    v = float(text)
    if not v >= 0.0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 0, got {text}")
    return v


def cmd_decode(args: argparse.Namespace) -> int:
    from zarco_tools.decode import main_decode

    return main_decode(args.log, args.variation, args.summary)


def cmd_replay(args: argparse.Namespace) -> int:
    from zarco_tools.replay import main_replay

    return main_replay(args)


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add this package's sub-commands to the ``zarco`` parser."""
    s = sub.add_parser("sim", help="simulate a scenario on the virtual clock")
    s.add_argument("scenario", help="scenario TOML file")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key by dotted path (repeatable)")
    s.add_argument("--seed", type=int, default=None, help="random seed (overrides the file)")
    s.add_argument("--report", metavar="FILE.json", help="write the JSON report here")
    s.add_argument("--plot", metavar="FILE.png", help="write the track/cross-track plot here")
    s.add_argument("-q", "--quiet", action="store_true", help="no running status")
    s.add_argument("--realtime", action="store_true",
                   help="run the simulated boat at 1x on a real clock, with whichever links "
                   "the scenario's [runtime] enables (shore, MAVLink), until SIGTERM/Ctrl-C "
                   "(exit 0) or scenario.max_duration_s")
    s.add_argument("--record", metavar="FILE.mcap",
                   help="record the run (every bus message, raw device bytes, the simulator's "
                   "truth) into this MCAP file, as zarco run records (zarco log reads it)")
    s.set_defaults(func=cmd_sim)

    n = sub.add_parser(
        "navreport", help="run the navigation EKF over NMEA captures and report its estimate",
        description="Feed each capture through the drivers' parsers into the navigation EKF "
                    "(timed by the capture's UTC, else at --line-rate) and report what it "
                    "estimated: a table per capture on stderr, then one JSON line (a dict "
                    "keyed by file) on stdout. Lines starting with # are skipped. Exit 0: "
                    "no EKF error; 1: some EKF error; 2: a file could not be read.")
    n.add_argument("logs", nargs="+", metavar="LOG", help="NMEA capture file(s)")
    n.add_argument("--variation", type=float, default=None, metavar="DEG",
                   help="magnetic variation (east +) for magnetic headings that carry none "
                        "(HDM; an HDG's own variation wins); without it they stay magnetic "
                        "and the report says so")
    n.add_argument("--line-rate", type=_positive_hz, default=5.0, metavar="HZ",
                   help="sentences per second for a capture without UTC times (default 5)")
    n.set_defaults(func=cmd_navreport)

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

    from zarco_tools.log.cli import register_log

    register_log(sub)

    from zarco_tools.shore.cli import register as register_shore

    register_shore(sub)
