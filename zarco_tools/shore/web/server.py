"""``zarco shore web``: a page on the operator's computer showing every vessel
heard on a map, live, with the commands its credentials allow.

The server (aiohttp) holds the zenoh sessions with the console's configuration
and credentials (:mod:`zarco_tools.shore.client`: a file or the environment,
never the command line) and serves one page, its script and its style from
the package (nothing from the internet).  The page opens a WebSocket on
which the server pushes every telemetry sample as it arrives (the state at
5 Hz); commands go back as ``POST /api/command``.

What keeps another web page (or another user of the computer's browser)
from using the operator's credentials through this server:

* it listens on ``127.0.0.1:8080`` unless told otherwise (``--listen``; any
  other address is warned about, and then the page asks for the key printed
  on the terminal, once per browser);
* the ``Host`` of every request must be the address it listens on
  (``localhost`` too, on loopback), against DNS rebinding;
* a page gets a session cookie (``HttpOnly``, ``SameSite=Strict``) and a
  per-session token written into the page; a command must carry both, come
  from the page's own origin (``Origin``; ``Sec-Fetch-Site`` same-origin)
  and be JSON;
* the WebSocket is refused (403) unless its ``Origin`` is the page's own and
  it carries the session cookie;
* the page may send only ``stop``, ``arm``, ``disarm``, ``mode`` (hold,
  return, idle), ``resume`` and ``follow``, and only to a vessel whose boat
  said these credentials are an operator's;
* a Content-Security-Policy lets the page load and connect to this server
  only, and no one may frame it.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import logging
import secrets
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aiohttp import WSMsgType, web

from zarco_tools.shore.web.hub import CommandError, Hub, Page

log = logging.getLogger("zarco.shore.web")

STATIC = Path(__file__).with_name("static")
#: the files the page loads (name → content type); nothing else is served
ASSETS = {"app.js": "text/javascript", "map.js": "text/javascript",
          "style.css": "text/css", "favicon.svg": "image/svg+xml"}
COOKIE = "zarco_web"
TOKEN_HEADER = "X-Zarco-Token"
#: sessions kept (oldest forgotten beyond)
MAX_SESSIONS = 256
#: largest command request (bytes)
MAX_BODY = 4096
CSP = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
       "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[IPv6]:PORT``) → (host, port); raises ValueError."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"--listen {text!r}: expected HOST:PORT (127.0.0.1:8080)")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    p = int(port)
    if not 1 <= p <= 65535:
        raise ValueError(f"--listen {text!r}: port must be 1..65535")
    return host, p


def is_loopback(host: str) -> bool:
    from zarco_runtime.links.shore.settings import is_loopback as loop_host

    return loop_host(host)


@dataclass(slots=True)
class Session:
    token: str
    created: float


class WebServer:
    """The page server (see the module docstring)."""

    def __init__(self, hub: Hub, host: str, port: int) -> None:
        self.hub = hub
        self.host = host
        self.port = port
        self.loopback = is_loopback(host)
        #: with a non-loopback address, a browser needs this key once (printed)
        self.key = "" if self.loopback else secrets.token_urlsafe(16)
        self.sessions: dict[str, Session] = {}
        self.index = (STATIC / "index.html").read_text(encoding="utf-8")
        self.assets = {n: (STATIC / n).read_bytes() for n in ASSETS}
        self.refused: dict[str, int] = {}
        self.app = web.Application(client_max_size=MAX_BODY,
                                   middlewares=[self._headers])
        self.app.router.add_get("/", self.page)
        self.app.router.add_get("/static/{name}", self.asset)
        self.app.router.add_get("/ws", self.websocket)
        self.app.router.add_post("/api/command", self.command)

    # ----------------------------------------------------------- checks

    def allowed_hosts(self) -> set[str]:
        hosts = {self.host, "localhost", "127.0.0.1", "::1"} if self.loopback else set()
        out = set()
        for h in hosts:
            out.add(f"[{h}]:{self.port}" if ":" in h else f"{h}:{self.port}")
        return out

    def _host_ok(self, request: web.Request) -> bool:
        if not self.loopback:
            return True  # any name of this computer; the key stands guard
        return request.host in self.allowed_hosts()

    def _origin_ok(self, request: web.Request) -> bool:
        origin = request.headers.get("Origin")
        return origin is not None and origin == f"http://{request.host}"

    def _session(self, request: web.Request) -> Session | None:
        sid = request.cookies.get(COOKIE, "")
        return self.sessions.get(sid) if sid else None

    def _refuse(self, why: str, status: int = 403) -> web.Response:
        self.refused[why] = self.refused.get(why, 0) + 1
        log.warning("refused: %s", why)
        return web.json_response({"ok": False, "reason": why}, status=status)

    @web.middleware
    async def _headers(self, request: web.Request, handler: Any) -> web.StreamResponse:
        if not self._host_ok(request):
            return self._refuse(f"host {request.host!r} is not this server's", 421)
        resp: web.StreamResponse = await handler(request)
        resp.headers.setdefault("Content-Security-Policy", CSP)
        resp.headers.setdefault("X-Frame-Options", "DENY")
        resp.headers.setdefault("X-Content-Type-Options", "nosniff")
        resp.headers.setdefault("Referrer-Policy", "no-referrer")
        resp.headers.setdefault("Cache-Control", "no-store")
        return resp

    # ----------------------------------------------------------- routes

    async def page(self, request: web.Request) -> web.Response:
        sess = self._session(request)
        fresh_sid = ""
        if sess is None:
            if self.key and not hmac.compare_digest(request.query.get("key", ""), self.key):
                return web.Response(status=401, content_type="text/plain",
                                    text="zarco shore web: open the address printed by "
                                    "`zarco shore web` (it carries the key).\n")
            fresh_sid = secrets.token_urlsafe(32)
            sess = Session(secrets.token_urlsafe(32), time.monotonic())
            self.sessions[fresh_sid] = sess
            while len(self.sessions) > MAX_SESSIONS:
                self.sessions.pop(next(iter(self.sessions)))
        if request.query.get("key"):  # the key's work is done: not in the address bar
            see = web.HTTPSeeOther("/")
            if fresh_sid:
                see.set_cookie(COOKIE, fresh_sid, httponly=True, samesite="Strict", path="/")
            raise see
        html = self.index.replace("{{TOKEN}}", sess.token)
        resp = web.Response(text=html, content_type="text/html", charset="utf-8")
        if fresh_sid:
            resp.set_cookie(COOKIE, fresh_sid, httponly=True, samesite="Strict", path="/")
        return resp

    async def asset(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        if name not in self.assets:
            raise web.HTTPNotFound()
        return web.Response(body=self.assets[name], content_type=ASSETS[name])

    async def websocket(self, request: web.Request) -> web.StreamResponse:
        if not self._origin_ok(request):
            return self._refuse(f"WebSocket from origin {request.headers.get('Origin')!r}")
        if self._session(request) is None:
            return self._refuse("WebSocket without a session (load the page first)")
        ws = web.WebSocketResponse(heartbeat=5.0, max_msg_size=4096, compress=False)
        await ws.prepare(request)
        page = Page()
        self.hub.pages.add(page)
        page.push(json.dumps(self.hub.hello(), separators=(",", ":")))
        sender = asyncio.create_task(self._send(ws, page), name="zarco-web-page")
        try:
            async for msg in ws:  # the page says nothing that matters; read until closed
                if msg.type == WSMsgType.ERROR:
                    break
        finally:
            self.hub.pages.discard(page)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sender
        return ws

    async def _send(self, ws: web.WebSocketResponse, page: Page) -> None:
        with contextlib.suppress(ConnectionError, RuntimeError):
            while not ws.closed:
                msg = await page.queue.get()
                await ws.send_str(msg)
                page.sent += 1
                page.bytes += len(msg)

    async def command(self, request: web.Request) -> web.Response:
        sess = self._session(request)
        if sess is None:
            return self._refuse("command without a session")
        if not self._origin_ok(request):
            return self._refuse(f"command from origin {request.headers.get('Origin')!r}")
        site = request.headers.get("Sec-Fetch-Site")
        if site is not None and site != "same-origin":
            return self._refuse(f"command from a {site} page")
        if not hmac.compare_digest(request.headers.get(TOKEN_HEADER, ""), sess.token):
            return self._refuse("command without this page's token")
        if request.content_type != "application/json":
            return self._refuse("command: not JSON", 415)
        try:
            body = await request.json()
        except (ValueError, UnicodeDecodeError):
            return self._refuse("command: not JSON", 400)
        if not isinstance(body, dict) or not isinstance(body.get("vessel"), str) \
                or not isinstance(body.get("name"), str):
            return self._refuse("command: expected {vessel, name, args}", 400)
        try:
            reply = await self.hub.command(body["vessel"], body["name"], body.get("args", {}))
        except CommandError as exc:
            return web.json_response({"ok": False, "vessel": body["vessel"],
                                      "name": body["name"], "reason": str(exc),
                                      "refused_by": "page server"}, status=400)
        return web.json_response(reply)


async def serve(hub: Hub, host: str, port: int, ready: Any = None) -> None:
    """Run the page server until cancelled; ``ready(url)`` once it listens."""
    server = WebServer(hub, host, port)
    runner = web.AppRunner(server.app, access_log=None, handle_signals=False)
    await runner.setup()
    site = web.TCPSite(runner, host, port)
    hb = asyncio.create_task(hub.heartbeat_loop(), name="zarco-web-heartbeat")
    try:
        await site.start()
        shown = f"[{host}]" if ":" in host else host
        url = f"http://{shown}:{port}/" + (f"?key={server.key}" if server.key else "")
        if ready is not None:
            ready(url)
        await asyncio.Event().wait()
    finally:
        hb.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await hb
        await runner.cleanup()
