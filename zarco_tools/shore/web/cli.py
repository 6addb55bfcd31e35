"""``zarco shore web [--listen HOST:PORT]``: the command line of the page server."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import signal
import sys
from typing import Any

DEFAULT_LISTEN = "127.0.0.1:8080"


def cmd_web(args: argparse.Namespace) -> int:
    from zarco_tools.shore.client import ShoreClient, ShoreError, load_console_config
    from zarco_tools.shore.web.hub import Hub
    from zarco_tools.shore.web.server import is_loopback, parse_listen, serve

    try:
        host, port = parse_listen(args.listen)
    except ValueError as exc:
        print(f"zarco shore web: {exc}", file=sys.stderr)
        return 2
    if not is_loopback(host):
        print(f"zarco shore web: WARNING: listening on {host}:{port}, not on this computer "
              "alone: whoever reaches that address and has the key printed below watches "
              "and commands the vessels with YOUR credentials", file=sys.stderr)
    cfg = load_console_config(args.config, args.connect or [], args.vessel or "")
    client = ShoreClient(cfg)
    hub = Hub(client, probe_timeout_s=args.timeout, command_timeout_s=args.timeout)

    async def main() -> int:
        loop = asyncio.get_running_loop()
        client.on_sample = hub.attach(loop)
        failed = await loop.run_in_executor(hub.pool, client.connect)
        for f in failed:
            print(f"zarco shore web: {f}", file=sys.stderr)
        if not client.sessions:
            raise ShoreError("no boat reachable")
        task = asyncio.current_task()
        assert task is not None
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, task.cancel)

        def ready(url: str) -> None:
            eps = ", ".join(c.endpoint for c, _ in client.sessions)
            print(f"zarco shore web: {url}  (boats: {eps}; user {cfg.user})", flush=True)

        try:
            await serve(hub, host, port, ready)
        except asyncio.CancelledError:
            return 0
        except OSError as exc:
            print(f"zarco shore web: cannot listen on {host}:{port}: {exc.strerror or exc}",
                  file=sys.stderr)
            return 2
        return 0

    try:
        return asyncio.run(main())
    finally:
        hub.close()
        with contextlib.suppress(Exception):
            client.close()


def add_parser(ss: Any, common: Any) -> None:
    """Add ``web`` to ``zarco shore``'s sub-commands (``common``: the shared options)."""
    w = ss.add_parser("web", parents=[common()],
                      help="the live map in a browser: vessels, the AUV, commands",
                      description="Serve the operator's live map on this computer "
                      "(http://127.0.0.1:8080/ by default) with the console's credentials.")
    w.add_argument("--listen", default=DEFAULT_LISTEN, metavar="HOST:PORT",
                   help=f"where the page is served (default {DEFAULT_LISTEN}; any other "
                   "address is warned about and needs the printed key)")
    w.set_defaults(shore_func=cmd_web)
