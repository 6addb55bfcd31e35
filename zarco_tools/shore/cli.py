"""``zarco shore``: the operator's console, a zenoh client of one or several boats.

    zarco shore [--connect EP]... [--config FILE] [--vessel NAME] COMMAND

``status`` shows every vessel heard (live; ``--once`` prints one table),
armed or not; ``arm``, ``disarm``, ``stop``, ``mode``, ``mission FILE``,
``follow``, ``resume``, ``param NAME VALUE`` send one command and print the
boat's acknowledgement or its reason for refusing; ``thrust`` is manual
teleoperation (renews the lease until stopped); ``rtcm SOURCE`` relays RTK
corrections; ``web`` serves the live map to a browser; ``foxglove`` serves
every vessel to Foxglove.

The boat boots disarmed: nothing moves until ``zarco shore arm`` is accepted
(it needs a valid position and heading, the thruster controller answering and
no failsafe active, and says which is missing otherwise).  ``disarm`` and
``stop`` go idle and disarmed.  ``status``, ``thrust``, ``rtcm`` (and ``web``
while a page is open) publish the operator heartbeat while they run (the
boat's ``link lost`` failsafe watches it); one-shot commands do not, so that
a single command does not arm it.

Exit status: 0 done / accepted; 1 refused by the boat; 2 configuration or
connection problem; 3 no reply (not an operator on that boat, or the vessel
is not reachable).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

EXIT_OK, EXIT_REFUSED, EXIT_CONFIG, EXIT_NO_REPLY = 0, 1, 2, 3


def _client(args: argparse.Namespace, subscribe: bool = True) -> Any:
    from zarco_tools.shore.client import ShoreClient, ShoreError, load_console_config

    cfg = load_console_config(args.config, args.connect or [], args.vessel or "")
    client = ShoreClient(cfg)
    failed = client.connect(subscribe=subscribe)
    for f in failed:
        print(f"zarco shore: {f}", file=sys.stderr)
    if not client.sessions:
        client.close()
        raise ShoreError("no boat reachable")
    return client


def _print_reply(replies: list[Any], name: str, quiet: bool = False) -> int:
    if not replies:
        print(f"zarco shore: {name}: no reply (not an operator on this boat, or the vessel "
              "is not reachable)", file=sys.stderr)
        return EXIT_NO_REPLY
    code = EXIT_OK
    for r in replies:
        if r.ok:
            if not quiet:
                print(f"{r.vessel}: {name} accepted; mode {r.mode} (id {r.id}, "
                      f"{r.rtt_s * 1000:.0f} ms)")
        else:
            print(f"{r.vessel}: {name} REFUSED: {r.reason} (mode {r.mode}, id {r.id})")
            code = EXIT_REFUSED
    return code


def _one(args: argparse.Namespace, name: str, cmd_args: dict[str, Any]) -> int:
    with _client(args) as c:
        vessel = c.resolve_vessel(args.wait)
        return _print_reply(c.command(vessel, name, cmd_args, args.timeout), name)


def cmd_stop(args: argparse.Namespace) -> int:
    return _one(args, "stop", {})


def cmd_arm(args: argparse.Namespace) -> int:
    return _one(args, "arm", {})


def cmd_disarm(args: argparse.Namespace) -> int:
    return _one(args, "disarm", {})


def param_value(text: str) -> Any:
    """A parameter's value as typed: JSON (``15``, ``2.5``, ``true``, ``[[41.1, -8.6],
    ...]``), or else the text itself (``hold``)."""
    try:
        return json.loads(text)
    except ValueError:
        return text


def cmd_param(args: argparse.Namespace) -> int:
    return _one(args, "param", {"name": args.name, "value": param_value(args.value)})


def cmd_follow(args: argparse.Namespace) -> int:
    return _one(args, "follow", {})


def cmd_resume(args: argparse.Namespace) -> int:
    return _one(args, "resume", {})


def cmd_mode(args: argparse.Namespace) -> int:
    a: dict[str, Any] = {"mode": args.mode}
    if (args.lat is None) != (args.lon is None):
        print("zarco shore: mode: give both --lat and --lon, or neither", file=sys.stderr)
        return EXIT_CONFIG
    if args.lat is not None:
        a.update(lat_deg=args.lat, lon_deg=args.lon)
    return _one(args, "mode", a)


def cmd_mission(args: argparse.Namespace) -> int:
    from zarco_tools.shore.mission_file import MissionFileError, load_mission

    try:
        m = load_mission(args.file)
    except MissionFileError as exc:
        print(f"zarco shore: mission: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    if args.speed is not None:
        m["speed_mps"] = args.speed
    m.setdefault("speed_mps", 1.0)
    m["start"] = not args.load_only
    print(f"mission {m['name']!r}: {len(m['waypoints'])} waypoints at "
          f"{m['speed_mps']:g} m/s" + (" (loaded, not started)" if args.load_only else ""))
    return _one(args, "mission", m)


@contextlib.contextmanager
def _until_signal() -> Iterator[threading.Event]:
    """An event set by SIGINT/SIGTERM (restored after)."""
    stop = threading.Event()
    old = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def cmd_status(args: argparse.Namespace) -> int:
    from zarco_tools.shore import view

    with _client(args) as c:
        if args.once:
            c.start_heartbeat()
            want = args.vessel or ""
            deadline = time.monotonic() + args.wait
            while time.monotonic() < deadline:  # every vessel's state (and health)
                snap = c.snapshot()
                if snap and all(v.state and v.health for v in snap.values()) and (
                        not want or want in snap) and (args.count <= len(snap)):
                    break
                time.sleep(0.05)
            snap = c.snapshot()
            if args.json:
                print(json.dumps({n: {"state": v.state, "health": v.health, "auv": v.auv,
                                      "events": v.events[-args.events:],
                                      "link_age_s": v.age_s()}
                                  for n, v in sorted(snap.items())}))
            else:
                print(view.plain(snap, args.events))
            return EXIT_OK if snap else EXIT_NO_REPLY
        endpoints = [cr.endpoint for cr, _ in c.sessions]
        c.start_heartbeat()
        with _until_signal() as stop:
            if args.plain or not sys.stdout.isatty():
                while not stop.wait(1.0):
                    print(view.plain(c.snapshot(), args.events), flush=True)
                    print(flush=True)
            else:
                from rich.live import Live

                with Live(view.rich_view(c.snapshot(), endpoints, args.events),
                          refresh_per_second=4, screen=False) as live:
                    while not stop.wait(0.25):
                        live.update(view.rich_view(c.snapshot(), endpoints, args.events))
    return EXIT_OK


def _keys(stop: threading.Event) -> Iterator[str | None]:
    """Keys pressed on the terminal (None every 0.1 s without one)."""
    import select
    import termios
    import tty

    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        while not stop.is_set():
            r, _, _ = select.select([fd], [], [], 0.1)
            yield sys.stdin.read(1) if r else None
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


def cmd_thrust(args: argparse.Namespace) -> int:
    """Manual teleoperation: the thrust command renewed every ``--period`` s (the
    boat's lease is supervisor.manual_lease_s), with the heartbeat, until stopped."""
    if not args.keys and (args.u1 is None or args.u2 is None):
        print("zarco shore: thrust: give U1 U2, or --keys", file=sys.stderr)
        return EXIT_CONFIG
    u = [args.u1 or 0.0, args.u2 or 0.0]
    for v in u:
        if not -100.0 <= v <= 100.0:
            print("zarco shore: thrust: U1, U2 must be within -100..100", file=sys.stderr)
            return EXIT_CONFIG
    with _client(args) as c, _until_signal() as stop:
        vessel = c.resolve_vessel(args.wait)
        c.start_heartbeat([vessel])
        if args.manual:
            code = _print_reply(c.command(vessel, "mode", {"mode": "manual"}, args.timeout),
                                "mode manual")
            if code:
                return code
        end = time.monotonic() + args.duration if args.duration else None
        sent = 0
        code = EXIT_OK
        if args.keys:
            print("w/s: both ±10   a/d: turn left/right   space: zero   q: quit",
                  file=sys.stderr)
        keys = _keys(stop) if args.keys else None
        next_t = time.monotonic()
        try:
            while not stop.is_set() and (end is None or time.monotonic() < end):
                if keys is not None:
                    k = next(keys, "q")
                    if k == "q":
                        break
                    step = {"w": (10, 10), "s": (-10, -10), "a": (-10, 10), "d": (10, -10)}
                    if k == " ":
                        u = [0.0, 0.0]
                    elif k in step:
                        u = [max(-100.0, min(100.0, u[i] + step[k][i])) for i in (0, 1)]
                    if k is not None:
                        print(f"\ru1 {u[0]:+4.0f}  u2 {u[1]:+4.0f}   ", end="", file=sys.stderr,
                              flush=True)
                        next_t = time.monotonic()
                if time.monotonic() < next_t:
                    if keys is None:
                        stop.wait(min(0.05, next_t - time.monotonic()))
                    continue
                next_t += args.period
                replies = c.command(vessel, "thrust", {"u1": u[0], "u2": u[1]}, args.timeout)
                sent += 1
                if not replies or not all(r.ok for r in replies):
                    code = _print_reply(replies, "thrust")
                    break
                if sent == 1 and keys is None:
                    _print_reply(replies, f"thrust {u[0]:g} {u[1]:g}")
        finally:
            if sent:  # zero at once rather than at the end of the lease
                with contextlib.suppress(Exception):
                    c.command(vessel, "thrust", {"u1": 0.0, "u2": 0.0}, args.timeout)
        if keys is not None:
            print(file=sys.stderr)
        if code == EXIT_OK:
            print(f"{vessel}: {sent} thrust commands accepted; thrust zeroed")
        return code


def cmd_rtcm(args: argparse.Namespace) -> int:
    """Relay RTCM3 corrections from SOURCE to the vessel (whole valid frames only)."""
    from drivers.rtcm import Rtcm3Filter, message_type
    from zarco_tools.shore.rtcm_source import SourceError, read_source

    with _client(args) as c, _until_signal() as stop:
        vessel = c.resolve_vessel(args.wait)
        c.start_heartbeat([vessel])
        flt = Rtcm3Filter()
        types: dict[int, int] = {}
        sent_bytes = 0
        last = time.monotonic()
        end = time.monotonic() + args.duration if args.duration else None
        try:
            for chunk in read_source(args.source, stop, args.baudrate, args.rate,
                                     c.config.ntrip_user, c.config.ntrip_password):
                frames = flt.feed(chunk)
                if frames:
                    data = b"".join(frames)
                    c.rtcm(vessel, data)
                    sent_bytes += len(data)
                    for f in frames:
                        mt = message_type(f)
                        if mt is not None:
                            types[mt] = types.get(mt, 0) + 1
                now = time.monotonic()
                if now - last >= args.report_s:
                    last = now
                    print(_rtcm_line(vessel, flt.counters, sent_bytes, types), file=sys.stderr)
                if end is not None and now >= end:
                    break
        except SourceError as exc:
            print(f"zarco shore: rtcm: {exc}", file=sys.stderr)
            return EXIT_CONFIG
        print(_rtcm_line(vessel, flt.counters, sent_bytes, types))
    return EXIT_OK


def _rtcm_line(vessel: str, counters: Any, sent: int, types: dict[int, int]) -> str:
    mt = " ".join(f"{k}×{v}" for k, v in sorted(types.items()))
    return (f"{vessel}: rtcm {counters['rtcm_frames']} frames ({sent} B) relayed, "
            f"{counters['rtcm_bad_frames']} bad frames, {counters['rtcm_dropped_bytes']} B "
            f"dropped; types {mt or '-'}")


def main_shore(args: argparse.Namespace) -> int:
    from zarco_tools.shore.client import ShoreError

    try:
        return int(args.shore_func(args))
    except ShoreError as exc:
        print(f"zarco shore: {exc}", file=sys.stderr)
        return EXIT_CONFIG


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``zarco shore`` to the ``zarco`` parser."""
    def common(top: bool = False) -> argparse.ArgumentParser:
        """The options every sub-command takes (before or after its name); only the
        top parser has defaults, so that a sub-command does not overwrite them."""
        c = argparse.ArgumentParser(add_help=False)

        def d(v: Any) -> Any:
            return v if top else argparse.SUPPRESS

        c.add_argument("--connect", action="append", metavar="ENDPOINT", default=d([]),
                       help="a boat's zenoh endpoint, tcp/HOST:PORT or tls/HOST:PORT "
                       "(repeatable: a fleet); default ZARCO_SHORE_CONNECT or the "
                       "configuration's connect")
        c.add_argument("--config", metavar="FILE", default=d(None),
                       help="console configuration (TOML; default ZARCO_SHORE_CONFIG or "
                       "~/.config/zarco/shore.toml): endpoints and where the credentials "
                       "are (credentials never go on the command line)")
        c.add_argument("--vessel", metavar="NAME", default=d(""),
                       help="the vessel to command (needed when several are heard)")
        c.add_argument("--timeout", type=float, default=d(3.0), metavar="S",
                       help="how long to wait for a reply (default 3 s)")
        c.add_argument("--wait", type=float, default=d(3.0), metavar="S",
                       help="how long to listen for vessels (default 3 s)")
        return c

    p = sub.add_parser("shore", parents=[common(top=True)],
                       help="the operator's console: watch and command vessels over zenoh",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.set_defaults(func=main_shore)
    ss = p.add_subparsers(dest="shore_command", required=True)

    s = ss.add_parser("status", parents=[common()], help="live view of the vessels")
    s.add_argument("--once", action="store_true", help="print one table and exit")
    s.add_argument("--json", action="store_true", help="with --once: JSON instead of a table")
    s.add_argument("--count", type=int, default=1, metavar="N",
                   help="with --once: wait (up to --wait) until N vessels are heard")
    s.add_argument("--plain", action="store_true", help="plain text, one table a second")
    s.add_argument("--events", type=int, default=5, metavar="N",
                   help="latest events shown per vessel")
    s.set_defaults(shore_func=cmd_status)

    for name, fn, text in (("arm", cmd_arm, "arm: allow thrust (checks position, heading, "
                            "thrusters, failsafes)"),
                           ("disarm", cmd_disarm, "disarm: idle, zero thrust"),
                           ("stop", cmd_stop, "stop: idle, zero thrust, disarmed (always "
                            "accepted)"),
                           ("follow", cmd_follow, "follow the AUV"),
                           ("resume", cmd_resume, "resume the last mission")):
        x = ss.add_parser(name, parents=[common()], help=text)
        x.set_defaults(shore_func=fn)

    pa = ss.add_parser("param", parents=[common()],
                       help="set a parameter of the running configuration (refused while "
                       "under way where unsafe)")
    pa.add_argument("name", help="a dotted configuration key, e.g. failsafe.link_lost_s")
    pa.add_argument("value", help="its value: a number, true/false, a word, or JSON")
    pa.set_defaults(shore_func=cmd_param)

    m = ss.add_parser("mode", parents=[common()], help="set the mode (hold: optionally at a point)")
    m.add_argument("mode", choices=["idle", "manual", "lines", "follow", "hold", "return"])
    m.add_argument("--lat", type=float, metavar="DEG", help="hold point latitude")
    m.add_argument("--lon", type=float, metavar="DEG", help="hold point longitude")
    m.set_defaults(shore_func=cmd_mode)

    mi = ss.add_parser("mission", parents=[common()],
                       help="send a lines mission (TOML waypoints or GeoJSON LineString)")
    mi.add_argument("file", help="mission file (.toml, .geojson)")
    mi.add_argument("--speed", type=float, metavar="M/S", help="speed along the lines")
    mi.add_argument("--load-only", action="store_true",
                    help="load it without starting (start later with mode lines)")
    mi.set_defaults(shore_func=cmd_mission)

    t = ss.add_parser("thrust", parents=[common()],
                      help="manual thrust (teleoperation): renewed until Ctrl-C")
    t.add_argument("u1", type=float, nargs="?", help="port thruster, -100..100")
    t.add_argument("u2", type=float, nargs="?", help="starboard thruster, -100..100")
    t.add_argument("--keys", action="store_true",
                   help="drive from the keyboard (w/s, a/d, space, q)")
    t.add_argument("--manual", action="store_true", help="switch to manual mode first")
    t.add_argument("--period", type=float, default=0.25, metavar="S",
                   help="renew every S seconds (the boat's lease is 1 s by default)")
    t.add_argument("--duration", type=float, default=0.0, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C)")
    t.set_defaults(shore_func=cmd_thrust)

    r = ss.add_parser("rtcm", parents=[common()],
                      help="relay RTK corrections (serial, tcp://, ntrip://, file://)")
    r.add_argument("source", help="serial path, tcp://HOST:PORT, ntrip://HOST[:PORT]/MOUNT "
                   "or file://PATH")
    r.add_argument("--baudrate", type=int, default=115200, help="serial speed (bit/s)")
    r.add_argument("--rate", type=float, default=2000.0, metavar="B/S",
                   help="pace of a file:// source")
    r.add_argument("--duration", type=float, default=0.0, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C or the source ends)")
    r.add_argument("--report-s", type=float, default=5.0, metavar="S",
                   help="progress line every S seconds (stderr)")
    r.set_defaults(shore_func=cmd_rtcm)

    from zarco_tools.shore.foxglove.cli import add_parser as add_foxglove
    from zarco_tools.shore.web.cli import add_parser as add_web

    add_web(ss, common)
    add_foxglove(ss, common)
