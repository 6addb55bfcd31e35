"""Parts of the web map and the Foxglove view without a boat: the commands the page
may send (refused with the field and the reason), ``--listen`` parsing, the key
a page server off loopback asks for (the real server, in-process, on a free
port), and the Foxglove messages made of shore samples."""

from __future__ import annotations

import asyncio
import contextlib
import http.cookiejar
import math
import urllib.error
import urllib.request
from typing import Any

import pytest
from shore_support import free_port

from zarco_tools.shore.client import ConsoleConfig, ShoreClient
from zarco_tools.shore.foxglove.bridge import messages
from zarco_tools.shore.web.hub import CommandError, Hub, check_command
from zarco_tools.shore.web.server import parse_listen, serve


@pytest.mark.parametrize(("name", "args", "want"), [
    ("stop", {}, {}), ("arm", {}, {}), ("disarm", {}, {}), ("resume", {}, {}),
    ("follow", {}, {}), ("mode", {"mode": "hold"}, {"mode": "hold"}),
    ("mode", {"mode": "return"}, {"mode": "return"}),
    ("mode", {"mode": "hold", "lat_deg": 41.2, "lon_deg": -8.7},
     {"mode": "hold", "lat_deg": 41.2, "lon_deg": -8.7}),
])
def test_the_page_commands(name: str, args: dict[str, Any], want: dict[str, Any]) -> None:
    assert check_command(name, args) == want


@pytest.mark.parametrize(("name", "args", "why"), [
    ("thrust", {"u1": 10, "u2": 10}, "unknown command 'thrust'"),
    ("mission", {}, "unknown command 'mission'"),
    ("param", {"name": "failsafe.link_lost_s", "value": 1}, "unknown command"),
    ("stop", {"now": True}, "stop: takes no arguments"),
    ("stop", [], "args: must be an object"),
    ("mode", {"mode": "manual"}, "mode: one of hold, return, idle"),
    ("mode", {}, "mode: one of"),
    ("mode", {"mode": "hold", "lat_deg": 41.0}, "give lat_deg and lon_deg, or neither"),
    ("mode", {"mode": "return", "lat_deg": 41.0, "lon_deg": -8.0}, "a point only for hold"),
    ("mode", {"mode": "hold", "lat_deg": 91.0, "lon_deg": 0.0}, "a latitude and a longitude"),
    ("mode", {"mode": "hold", "lat_deg": math.nan, "lon_deg": 0.0}, "a latitude"),
    ("mode", {"mode": "hold", "lat_deg": True, "lon_deg": 0.0}, "a latitude"),
    ("mode", {"mode": "hold", "lat_deg": "41", "lon_deg": 0.0}, "a latitude"),
    ("mode", {"mode": "hold", "speed": 3}, "unexpected ['speed']"),
])
def test_other_commands_are_refused_with_the_reason(name: str, args: Any, why: str) -> None:
    with pytest.raises(CommandError) as exc:
        check_command(name, args)
    assert why in str(exc.value)


def test_listen_addresses() -> None:
    assert parse_listen("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert parse_listen("[::1]:9000") == ("::1", 9000)
    assert parse_listen("0.0.0.0:1") == ("0.0.0.0", 1)
    for bad in ("8080", "localhost", ":8080", "127.0.0.1:0", "127.0.0.1:70000", "h:p"):
        with pytest.raises(ValueError, match="--listen"):
            parse_listen(bad)


def test_off_loopback_the_page_needs_the_printed_key() -> None:
    port = free_port()
    hub = Hub(ShoreClient(ConsoleConfig([], user="alice")))
    urls: list[str] = []

    def get(url: str, opener: Any) -> tuple[int, str]:
        try:
            with opener.open(url, timeout=10.0) as r:
                return int(r.status), r.read().decode()
        except urllib.error.HTTPError as exc:
            return int(exc.code), exc.read().decode()

    async def main() -> None:
        task = asyncio.create_task(serve(hub, "0.0.0.0", port, urls.append))
        loop = asyncio.get_running_loop()
        try:
            while not urls:
                await asyncio.sleep(0.05)
            url = urls[0]
            assert url.startswith(f"http://0.0.0.0:{port}/?key=")
            key = url.split("key=")[1]
            base = f"http://127.0.0.1:{port}/"
            plain = urllib.request.build_opener()
            st, body = await loop.run_in_executor(None, get, base, plain)
            assert st == 401 and "key" in body
            st, _ = await loop.run_in_executor(None, get, base + "?key=" + "x" * len(key), plain)
            assert st == 401
            jar = http.cookiejar.CookieJar()
            browser = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar))
            st, body = await loop.run_in_executor(None, get, base + "?key=" + key, browser)
            assert st == 200 and 'name="zarco-token"' in body  # redirected to the page
            assert any(c.name == "zarco_web" for c in jar)
            st, body = await loop.run_in_executor(None, get, base, browser)  # the cookie
            assert st == 200 and "{{TOKEN}}" not in body
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    try:
        asyncio.run(main())
    finally:
        hub.close()


@pytest.mark.parametrize(("host", "warned"), [("0.0.0.0", True), ("127.0.0.1", False),
                                              ("::1", False)])
def test_listening_off_loopback_is_warned_about(tmp_path: Any, host: str,
                                                warned: bool) -> None:
    """``zarco shore web --listen`` off loopback warns before anything else (here
    no boat answers, and it ends with that reason: exit 2)."""
    import os
    import subprocess
    import sys

    from shore_support import ROOT, write_credentials

    cred = write_credentials(tmp_path / "cred", "alice", "x")
    cfg = tmp_path / "console.toml"
    cfg.write_text(f'connect = ["tcp/127.0.0.1:{free_port()}"]\n'
                   f'credentials_file = "{cred}"\n')
    cfg.chmod(0o600)
    listen = f"[{host}]:{free_port()}" if ":" in host else f"{host}:{free_port()}"
    env = {**os.environ, "ZARCO_SHORE_CONFIG": str(cfg)}
    r = subprocess.run([sys.executable, "-m", "zarco_runtime.cli", "shore", "web",
                        "--listen", listen], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "no boat reachable" in r.stderr, r.stderr
    assert ("WARNING: listening on" in r.stderr) is warned, r.stderr
    assert "Traceback" not in r.stderr


def test_foxglove_messages_of_shore_samples() -> None:
    st = {"t": 1.7e9 + 0.25, "lat_deg": 41.1, "lon_deg": -8.6, "pos_valid": True, "mode": "lines"}
    out = dict(messages("state", st))
    assert out["/shore/state"] is st
    fix = out["/foxglove/vessel"]
    assert (fix["latitude"], fix["longitude"]) == (41.1, -8.6)
    assert fix["timestamp"] == {"sec": 1_700_000_000, "nsec": 250_000_000}
    assert fix["position_covariance_type"] == 0
    # no position, no fix; an AUV only while tracked, with its covariance (ENU)
    assert [t for t, _ in messages("state", {**st, "pos_valid": False})] == ["/shore/state"]
    assert [t for t, _ in messages("state", {**st, "lat_deg": None})] == ["/shore/state"]
    a = {"t": 1.7e9, "lat_deg": 41.0, "lon_deg": -8.0, "status": "tracking",
         "pos_cov_m2": [4.0, 0.5, 1.0]}
    fa = dict(messages("auv", a))["/foxglove/auv"]
    assert fa["position_covariance"] == [1.0, 0.5, 0.0, 0.5, 4.0, 0.0, 0.0, 0.0, 0.0]
    assert fa["position_covariance_type"] == 3
    for status in ("acquiring", "lost"):
        assert [t for t, _ in messages("auv", {**a, "status": status})] == ["/shore/auv"]
    ev = dict(messages("event", {"t": 5.0, "kind": "failsafe", "text": "link lost: hold",
                                 "source": "supervisor"}))["/foxglove/events"]
    assert ev["level"] == 3 and ev["message"] == "link lost: hold"
    assert ev["name"] == "failsafe/supervisor"
    assert messages("health", {"t": 1.0}) == [] and messages("state", {"t": None}) == []
