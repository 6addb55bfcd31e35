"""``zarco`` command line: ``sim`` (virtual clock), ``run`` (the boat), ``navreport``
(the navigation EKF over NMEA captures); ``hil``, ``replay``, ``decode`` come from
:mod:`hil.cli`."""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import signal
import sys
from pathlib import Path
from typing import Any

from zarco_runtime.config import ConfigError


def _fmt(v: Any, unit: str = "m") -> str:
    return f"{v:.3f} {unit}" if isinstance(v, (int, float)) else str(v)


def follow_summary(report: dict[str, Any]) -> str:
    """One screen of a follow-the-AUV run."""
    lines = [
        f"scenario {report['scenario']}  seed {report['seed']}  ({report['stop']})",
        f"simulated {report['sim_seconds']:.1f} s in {report['wall_seconds']:.2f} s wall "
        f"= {report['speedup']:.0f}× real time",
        f"passive fixes: {report['fixes']}, median interval {report['fix_interval_s']:.2f} s, "
        f"error RMS {_fmt(report['fix_error_rms_m'])}; track error RMS "
        f"{_fmt(report['track_error_rms_m'])}",
        f"AUV course error RMS (straight legs) {report['course_error_rms_deg']:.2f}°",
        f"ASV–AUV distance: median {_fmt(report['distance_median_m'])}  "
        f"p95 {_fmt(report['distance_p95_m'])}  max {_fmt(report['distance_max_m'])}",
        f"track lost {report['track_lost_events']} times",
        "",
        " turn at   detect   recovery   max distance",
    ]
    for tr in report["turns"]:
        lines.append(f" {tr['t_s']:7.1f}  {tr['detect_s']:6.1f} s  {tr['recovery_s']:6.1f} s  "
                     f"{tr['distance_max_m']:7.2f} m")
    return "\n".join(lines)


def summary(report: dict[str, Any]) -> str:
    """One screen of headline figures."""
    if "xtrack_rms_m" not in report:
        return follow_summary(report)
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
            f" {leg['leg']:3d}  {leg['speed_mps']:4.2f}  {leg['xtrack_rms_m']:7.3f}  "
            f"{leg['xtrack_p95_m']:7.3f}  {leg['xtrack_max_m']:7.3f}  {leg['overshoot_m']:7.2f}"
        )
    if report.get("faults"):
        lines.append("")
        lines.append("faults: " + "; ".join(report["faults"]))
    return "\n".join(lines)


def cmd_sim(args: argparse.Namespace) -> int:
    from zarco_runtime.scenario import load_scenario
    from zarco_runtime.simulation import StatusLine, run_scenario

    scn = load_scenario(args.scenario, args.set, args.seed)
    status = None if args.quiet else StatusLine()
    try:
        res = run_scenario(scn, progress=status)
    finally:
        if status is not None:
            status.close()
    if args.report:
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        Path(args.report).write_text(json.dumps(res.report, indent=2) + "\n")
    if args.plot:
        from zarco_runtime.plot import plot_follow, plot_lines

        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
        if scn.mission.kind == "follow":
            plot_follow(args.plot, res.log, res.extra,
                        f"{scn.scenario.name}: seed {scn.scenario.seed}, distance median "
                        f"{res.report['distance_median_m']:.2f} m")
        else:
            plot_lines(args.plot, res.log, res.legs,
                       f"{scn.scenario.name}: seed {scn.scenario.seed}, "
                       f"RMS {res.report['xtrack_rms_m']:.3f} m")
    print(summary(res.report))
    if args.report:
        print(f"\nreport: {args.report}")
    if args.plot:
        print(f"plot:   {args.plot}")
    return 0


def _status_file(path: str, runtime: Any) -> Any:
    """``--status FILE``: one JSON line per device health transition (with its
    counters) while running, and a ``"final": true`` line with every device's
    counters on exit.  Returns the function that writes the final line."""
    import time

    from zarco_runtime.messages import DeviceHealth

    fh = Path(path).open("a", buffering=1)  # noqa: SIM115 (closed by final())
    last: dict[str, tuple[str, str]] = {}

    def on_health(m: DeviceHealth) -> None:
        if last.get(m.device) != (m.state.value, m.reason):
            last[m.device] = (m.state.value, m.reason)
            fh.write(json.dumps({"wall": round(time.time(), 3), "t": round(m.t, 3),
                                 "device": m.device, "state": m.state.value,
                                 "reason": m.reason, "counters": m.counters}) + "\n")

    runtime.bus.listen(DeviceHealth, on_health)

    def final() -> None:
        devs = {d.name: {"state": d.state.value, "reason": d.reason,
                         "counters": dict(d.counters)}
                for d in (runtime.gps, runtime.compass, runtime.thrusters)}
        ctl = runtime.control
        fh.write(json.dumps({"final": True, "wall": round(time.time(), 3), "devices": devs,
                             "control": {"ticks": ctl.ticks, "faults": ctl.faults,
                                         "saturated_ticks": ctl.saturated_ticks,
                                         "period_jitter_hist": getattr(
                                             ctl, "period_jitter_hist", None)}}) + "\n")
        fh.close()

    return final


def cmd_run(args: argparse.Namespace) -> int:
    from zarco_runtime.geodesy import LocalFrame
    from zarco_runtime.guidance.mission import build_legs
    from zarco_runtime.runtime import Runtime
    from zarco_runtime.scenario import load_runtime_config

    cfg, mission = load_runtime_config(args.config, args.set)
    o = cfg.origin
    legs = build_legs(mission, LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)) if mission else []
    runtime = Runtime(cfg, legs)
    final = _status_file(args.status, runtime) if args.status else None

    async def main() -> None:
        task = asyncio.current_task()
        loop = asyncio.get_running_loop()
        assert task is not None
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, task.cancel)
        try:
            await runtime.run()
        except asyncio.CancelledError:
            logging.getLogger("zarco").info("stopping: signal received")
        finally:
            if final is not None:
                final()

    asyncio.run(main())
    return 0


def _positive_hz(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (v > 0.0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return v


def cmd_navreport(args: argparse.Namespace) -> int:
    from zarco_runtime.navigation.capture_report import main_navreport

    return main_navreport(args.logs, args.variation, args.line_rate)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="zarco", description="Zarco ASV runtime")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("sim", help="simulate a scenario on the virtual clock")
    s.add_argument("scenario", help="scenario TOML file")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key by dotted path (repeatable)")
    s.add_argument("--seed", type=int, default=None, help="random seed (overrides the file)")
    s.add_argument("--report", metavar="FILE.json", help="write the JSON report here")
    s.add_argument("--plot", metavar="FILE.png", help="write the track/cross-track plot here")
    s.add_argument("-q", "--quiet", action="store_true", help="no running status")
    s.set_defaults(func=cmd_sim)

    r = sub.add_parser("run", help="run on the vessel (real devices)")
    r.add_argument("--config", required=True, help="runtime TOML (config/zarco.toml)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    r.add_argument("--status", metavar="FILE.jsonl", help="append device health transitions "
                   "(JSON lines, with counters) here, and every device's counters on exit")
    r.set_defaults(func=cmd_run)

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

    from hil.cli import register

    register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args))
    except ConfigError as exc:
        print(f"zarco: configuration refused: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
