"""``zarco`` command line.

``zarco run`` (the boat) is built in.  Every other sub-command (``sim``,
``hil``, ``decode``, ``replay``, ``navreport``, ...) belongs to a package that
stands beside the onboard runtime (the simulator, HIL, evaluation tools) and
is found through the ``zarco.commands`` entry points, loaded only when one of
them is asked for: ``zarco run`` never imports the simulator, HIL, plotting
or evaluation code.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import signal
import sys
from pathlib import Path
from typing import Any

from zarco_core.config import ConfigError


def _status_file(path: str, runtime: Any) -> Any:
    """``--status FILE``: one JSON line per device health transition (with its
    counters) while running, and a ``"final": true`` line with every device's
    counters on exit.  Returns the function that writes the final line."""
    import time

    from zarco_core.messages import DeviceHealth

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
    from zarco_core.geodesy import LocalFrame
    from zarco_runtime.config_file import load_runtime_config
    from zarco_runtime.guidance.mission import build_legs
    from zarco_runtime.runtime import Runtime

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


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="zarco", description="Zarco ASV runtime")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run on the vessel (real devices)")
    r.add_argument("--config", required=True, help="runtime TOML (config/zarco.toml)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    r.add_argument("--status", metavar="FILE.jsonl", help="append device health transitions "
                   "(JSON lines, with counters) here, and every device's counters on exit")
    r.set_defaults(func=cmd_run)

    for ep in _tool_commands(argv):
        ep.load()(sub)
    return p


#: sub-commands of this module; any other comes from a ``zarco.commands`` entry point
BUILTIN = ("run",)


def _tool_commands(argv: list[str] | None) -> list[Any]:
    """The ``zarco.commands`` entry points to load for ``argv``: none for a built-in
    sub-command, else all of them (``zarco --help`` lists every command)."""
    args = sys.argv[1:] if argv is None else argv
    words = [a for a in args if not a.startswith("-")]
    if words and words[0] in BUILTIN:
        return []
    from importlib.metadata import entry_points

    return sorted(entry_points(group="zarco.commands"), key=lambda e: e.name)


def main(argv: list[str] | None = None) -> int:
    args = build_parser(argv).parse_args(argv)
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
