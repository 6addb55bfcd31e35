"""``zarco shore foxglove [--port 8765]``: the command line of the live Foxglove view."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from typing import Any

DEFAULT_PORT = 8765


def cmd_foxglove(args: argparse.Namespace) -> int:
    from zarco_tools.shore.foxglove.layout import LAYOUT_FILE

    if args.save_layout:
        try:
            Path(args.save_layout).write_text(LAYOUT_FILE.read_text(encoding="utf-8"),
                                              encoding="utf-8")
        except OSError as exc:
            print(f"zarco shore foxglove: {args.save_layout}: {exc.strerror or exc}",
                  file=sys.stderr)
            return 2
        print(f"zarco shore foxglove: layout written to {args.save_layout} (Foxglove: "
              "Layouts → Import from file)")
        return 0
    from zarco_runtime.links.shore.settings import is_loopback
    from zarco_tools.shore.client import ShoreClient, ShoreError, load_console_config
    from zarco_tools.shore.foxglove.bridge import Bridge

    if not 1 <= args.port <= 65535:
        print("zarco shore foxglove: --port must be 1..65535", file=sys.stderr)
        return 2
    if not is_loopback(args.host):
        print(f"zarco shore foxglove: WARNING: serving on {args.host}:{args.port}: whoever "
              "reaches it sees every vessel heard (the Foxglove protocol has no login)",
              file=sys.stderr)
    cfg = load_console_config(args.config, args.connect or [], args.vessel or "")
    bridge = Bridge(cfg.vessel)
    try:
        bridge.start(args.host, args.port)
    except Exception as exc:  # the SDK's bind error
        print(f"zarco shore foxglove: cannot serve on {args.host}:{args.port}: {exc}",
              file=sys.stderr)
        return 2
    client = ShoreClient(cfg, on_sample=bridge.on_sample)
    try:
        failed = client.connect()
        for f in failed:
            print(f"zarco shore foxglove: {f}", file=sys.stderr)
        if not client.sessions:
            raise ShoreError("no boat reachable")
        stop = threading.Event()
        old = {s: signal.signal(s, lambda *_: stop.set())
               for s in (signal.SIGINT, signal.SIGTERM)}
        eps = ", ".join(c.endpoint for c, _ in client.sessions)
        print(f"zarco shore foxglove: ws://{args.host}:{args.port}  (Foxglove: Open "
              f"connection → Foxglove WebSocket; boats: {eps})", flush=True)
        try:
            stop.wait()
        finally:
            for s, h in old.items():
                signal.signal(s, h)
    finally:
        client.close()
        bridge.stop()
    return 0


def add_parser(ss: Any, common: Any) -> None:
    """Add ``foxglove`` to ``zarco shore``'s sub-commands."""
    f = ss.add_parser("foxglove", parents=[common()],
                      help="every vessel heard, live, for Foxglove (WebSocket server)",
                      description="Serve every vessel heard to Foxglove (Open connection → "
                      "Foxglove WebSocket) with the recordings' topics and schemas, with "
                      "the console's credentials.")
    f.add_argument("--port", type=int, default=DEFAULT_PORT,
                   help=f"the WebSocket server's port (default {DEFAULT_PORT})")
    f.add_argument("--host", default="127.0.0.1",
                   help="the address it listens on (default 127.0.0.1; another is warned "
                   "about)")
    f.add_argument("--save-layout", metavar="FILE",
                   help="write the Foxglove layout (map, distance, courses, mode, events) "
                   "to FILE and exit")
    f.set_defaults(shore_func=cmd_foxglove)
