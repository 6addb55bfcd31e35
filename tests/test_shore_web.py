"""``zarco shore web`` in a real browser (the distribution's Chromium, driven by
Playwright) against two simulated boats (``zarco sim --realtime``, their own
processes, ``auth = "usrpwd"``): ``alpha`` follows the AUV, ``beta`` sails the
rectangle.  Two page servers, each with a console configuration file: alice
(an operator of both) and bob (a viewer of alpha).  An independent zenoh
client (alice's credentials) is the reference for what the boats publish
and reply.

The boat and the AUV move on the map where their telemetry says (checked
against pymap3d); the distance shown is the ``auv`` key's; the stop button
and the Escape key stop the boat; a refusal's text is the boat's; a viewer
sees no commands and the page server sends none for it; a page of another
origin gets no WebSocket and its commands are refused."""

from __future__ import annotations

import http.server
import json
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pymap3d
import pytest
from shore_support import (
    RECT,
    ROOT,
    Boat,
    boats,
    connect_when_up,
    free_port,
    write_credentials,
    write_users,
)
from web_support import WebProcess, console_config, launch

from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient

playwright_sync = pytest.importorskip("playwright.sync_api")

FOLLOW = ROOT / "config" / "scenarios" / "follow_turn.toml"


@dataclass
class Rig:
    observer: ShoreClient
    op: Any          # alice's page
    viewer: Any      # bob's page
    browser: Any
    op_web: WebProcess
    view_web: WebProcess


def _text(page: Any, sel: str, cond: str, timeout_ms: float = 30_000) -> None:
    """Wait until the text of ``sel`` satisfies ``cond`` (JavaScript, on ``t``)."""
    page.wait_for_function(f"() => {{ const t = document.querySelector({sel!r}).textContent;"
                           f" return {cond}; }}", timeout=timeout_ms)


def _until(pred: Callable[[], Any], timeout_s: float = 20.0, what: str = "") -> Any:
    deadline = time.monotonic() + timeout_s
    last: Any = None
    while time.monotonic() < deadline:
        last = pred()
        if last:
            return last
        time.sleep(0.05)
    raise AssertionError(f"never {what or pred}; last {last!r}")


def _observer(eps: list[str], user: str, password: str) -> ShoreClient:
    c = ShoreClient(ConsoleConfig([Credentials(e, user, password) for e in eps], user=user))
    failed = c.connect()
    if failed or set(c.wait_vessels(10.0, "beta")) < {"alpha", "beta"}:
        c.close()
        raise ConnectionError(failed or "not both vessels heard")
    return c


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    tmp = tmp_path_factory.mktemp("web")
    users = write_users(tmp / "users", {"alice": "op-secret", "bob": "view-secret"})
    ea, eb = f"tcp/127.0.0.1:{free_port()}", f"tcp/127.0.0.1:{free_port()}"
    auth = ['runtime.shore.auth="usrpwd"', f'runtime.shore.users_file="{users}"',
            'runtime.shore.operators=["alice"]', 'runtime.shore.viewers=["bob"]']
    alpha = Boat([f'runtime.shore.listen=["{ea}"]', "runtime.shore.vessel=alpha", *auth,
                  "auv.start_delay_s=5.0"], scenario=FOLLOW, log=tmp / "alpha.log")
    beta = Boat([f'runtime.shore.listen=["{eb}"]', "runtime.shore.vessel=beta", *auth],
                scenario=RECT, log=tmp / "beta.log")
    alice = write_credentials(tmp / "alice.cred", "alice", "op-secret")
    bob = write_credentials(tmp / "bob.cred", "bob", "view-secret")
    with boats(alpha, beta):
        observer = connect_when_up(lambda: _observer([ea, eb], "alice", "op-secret"), 40.0)
        op_web = WebProcess(console_config(tmp / "alice.toml", [(ea, alice), (eb, alice)],
                                           vessel="alpha"), free_port(),
                            log=tmp / "web-alice.log").start()
        view_web = WebProcess(console_config(tmp / "bob.toml", [(ea, bob)]), free_port(),
                              log=tmp / "web-bob.log").start()
        try:
            with playwright_sync.sync_playwright() as p:
                browser = launch(p)
                op = browser.new_context(viewport={"width": 1280, "height": 800}).new_page()
                viewer = browser.new_context(viewport={"width": 1280, "height": 800}).new_page()
                errors: list[str] = []
                for pg in (op, viewer):
                    pg.on("pageerror", lambda e: errors.append(str(e)))
                    pg.set_default_timeout(20_000)
                op.goto(op_web.url)
                viewer.goto(view_web.url)
                yield Rig(observer, op, viewer, browser, op_web, view_web)
                browser.close()
                assert errors == [], errors  # the page's script never failed
        finally:
            op_web.stop()
            view_web.stop()
            observer.close()


def _marker(page: Any, sel: str) -> tuple[float, float, float] | None:
    got = page.evaluate(f"""() => {{ const m = document.querySelector("{sel}");
        return m ? [m.dataset.n, m.dataset.e, m.dataset.t] : null; }}""")
    return None if got is None or got[2] in (None, "") else (float(got[0]), float(got[1]),
                                                              float(got[2]))


def _ned(lat: float, lon: float, origin: dict[str, float]) -> tuple[float, float]:
    n, e, _ = pymap3d.geodetic2ned(lat, lon, 0.0, origin["lat_deg"], origin["lon_deg"], 0.0)
    return float(n), float(e)


def test_boat_and_auv_move_on_the_map_where_their_telemetry_says(rig: Rig) -> None:
    page = rig.op
    _until(lambda: page.evaluate("() => zarco.selected()") == "alpha", what="alpha selected")
    origin = _until(lambda: (rig.observer.snapshot()["alpha"].map or {}).get("origin"),
                    what="alpha's map")
    for sel, kind in (("#boat", "state"), ("#auv", "auv")):
        first = _until(lambda sel=sel: _marker(page, sel), what=f"{sel} drawn")
        # it moves (the AUV sets off 5 s into the run, at 1 m/s; the boat follows)
        _until(lambda sel=sel, first=first: (m := _marker(page, sel)) is not None and
               ((m[0] - first[0]) ** 2 + (m[1] - first[1]) ** 2) ** 0.5 > 2.0,
               timeout_s=60.0, what=f"{sel} moving")
        # where the boat's own frame puts it: the observer's sample of the same time
        checked = 0
        deadline = time.monotonic() + 20.0
        while checked < 3 and time.monotonic() < deadline:
            m = _marker(page, sel)
            v = rig.observer.snapshot()["alpha"]
            sample = getattr(v, kind)
            if m is not None and sample and sample.get("t") == m[2]:
                n, e = _ned(sample["lat_deg"], sample["lon_deg"], origin)
                assert abs(m[0] - n) < 0.005 and abs(m[1] - e) < 0.005, (sel, m, n, e)
                checked += 1
                time.sleep(0.3)
            time.sleep(0.02)
        assert checked == 3, f"{sel}: no marker matched the observer's samples"
    # the AUV's 1σ ellipse and its fitted line are drawn
    page.wait_for_selector("#auv-ellipse", state="attached")
    page.wait_for_selector("#auv-line", state="attached", timeout=40_000)
    # the beacons, the listening buoy's beacon and home are on the map
    assert page.locator("[data-beacon]").count() == 3
    page.wait_for_selector("#home", state="attached")


def test_the_map_frame_is_the_boats_own(rig: Rig) -> None:
    """The page's plane is the boat's NED frame: pymap3d's, to the millimetre,
    over 10 km about origins far apart."""
    import random

    rnd = random.Random(23)
    for _ in range(5):
        lat0, lon0 = rnd.uniform(-70.0, 70.0), rnd.uniform(-180.0, 180.0)
        pts = [(rnd.uniform(-5000.0, 5000.0), rnd.uniform(-5000.0, 5000.0)) for _ in range(20)]
        geo = [pymap3d.ned2geodetic(n, e, 0.0, lat0, lon0, 0.0)[:2] for n, e in pts]
        got = rig.op.evaluate("""([lat0, lon0, geo]) => { const f = new ZarcoLocalFrame(lat0, lon0);
            return geo.map(([a, b]) => [f.toLocal(a, b), f.toGeo(...f.toLocal(a, b))]); }""",
                              [lat0, lon0, [list(map(float, g)) for g in geo]])
        for (n, e), (lat, lon), (local, back) in zip(pts, geo, got, strict=True):
            # the plane through the origin (down 0), as pymap3d's NED at the surface
            n2, e2, _ = pymap3d.geodetic2ned(lat, lon, 0.0, lat0, lon0, 0.0)
            assert abs(local[0] - n2) < 1e-3 and abs(local[1] - e2) < 1e-3
            # back to degrees (the cursor's reading): within 1e-7° (1 cm)
            assert abs(back[0] - lat) < 1e-7 and abs(back[1] - lon) < 1e-7
            assert abs(n2 - n) < 5.0 and abs(e2 - e) < 5.0  # (the surface is not the plane)


def test_the_auv_plan_is_drawn(rig: Rig) -> None:
    """The AUV's a-priori plan given with ``follow`` reaches the map (the ``map`` key)."""
    page = rig.op
    origin = rig.observer.snapshot()["alpha"].map["origin"]
    # the scenario's AUV legs (north, east metres), as an operator would give them
    ned = [(100.0, 100.0), (300.0, 100.0), (300.0, 300.0)]
    plan = [list(pymap3d.ned2geodetic(n, e, 0.0, origin["lat_deg"], origin["lon_deg"],
                                      0.0)[:2]) for n, e in ned]
    _following(rig)
    r = rig.observer.command("alpha", "follow", {"auv_plan": [[float(a), float(b)]
                                                              for a, b in plan]})
    assert len(r) == 1 and r[0].ok, r
    page.wait_for_selector("#auv-plan", state="attached", timeout=30_000)
    pts = (page.get_attribute("#auv-plan", "points") or "").split()
    assert len(pts) == 3
    got = rig.observer.snapshot()["alpha"].map["auv_plan"]
    assert all(abs(g[0] - p[0]) < 1e-7 and abs(g[1] - p[1]) < 1e-7
               for g, p in zip(got, plan, strict=True))


def test_distance_shown_is_the_auv_keys(rig: Rig) -> None:
    page = rig.op
    seen: set[float] = set()
    deadline = time.monotonic() + 40.0
    while len(seen) < 4 and time.monotonic() < deadline:
        t, text, sound = page.evaluate("""() => { const a = zarco.latest("auv");
            return [a ? a.t : null, document.getElementById("distance").textContent,
                    document.getElementById("sound-speed").textContent]; }""")
        ref = rig.observer.snapshot()["alpha"].auv
        if t is not None and ref.get("t") == t and ref.get("distance_m") is not None:
            # shown to 0.1 m: the key's value to the display's half unit (a tie such as
            # 0.25 rounds up in the page, to even in Python)
            assert abs(float(text) - ref["distance_m"]) <= 0.05 + 1e-9, (text, ref)
            assert len(text.split(".")[1]) == 1
            # the sound speed the tracker ranges with and its 1σ, "c ± σ m/s" to 0.1
            c, pm, sigma, unit = sound.split()
            assert (pm, unit) == ("±", "m/s"), sound
            assert abs(float(c) - ref["sound_speed_mps"]) <= 0.05 + 1e-9, (sound, ref)
            assert abs(float(sigma) - ref["sound_speed_sigma_mps"]) <= 0.05 + 1e-9, (sound,
                                                                                       ref)
            seen.add(t)
        time.sleep(0.1)
    assert len(seen) >= 4, f"only {len(seen)} AUV updates compared"
    # the sparkline draws them
    pts = page.get_attribute("#spark polyline", "points") or ""
    assert len(pts.split()) >= 4


def _boat_t(rig: Rig, vessel: str) -> float:
    """The boat's clock (s) in its latest state: an event after now has a later t."""
    return float(rig.observer.snapshot()[vessel].state["t"])


def _acks(rig: Rig, vessel: str, what: str, since: float) -> list[str]:
    """The boat's acknowledgements starting ``what`` stamped at or after ``since``
    (boat time): the observer keeps only the latest events, so they are told
    apart by time, not counted."""
    v = rig.observer.snapshot()[vessel]
    return [e["text"] for e in v.events if e.get("kind") == "ack"
            and e["text"].startswith(what) and float(e["t"]) >= since]


def _shows(rig: Rig, page: Any, mode: str, since: float) -> bool:
    """The page shows alpha's mode and it is ``mode``; for return, hold also
    once the boat has said it arrived home (at or after ``since``, boat time):
    a boat already within reach of home holds there at once."""
    shown, boat = page.text_content("#mode"), _mode(rig, "alpha")
    if shown == boat == mode:
        return True
    arrived = any("arrived home" in e["text"] and float(e["t"]) >= since
                  for e in rig.observer.snapshot()["alpha"].events)
    return mode == "return" and arrived and shown == boat == "hold"


def _mode(rig: Rig, vessel: str) -> str:
    return str(rig.observer.snapshot()[vessel].state.get("mode"))


def _stopped(rig: Rig) -> None:
    """The boat's own state says alpha is idle, as the observer (a subscriber
    apart from the page's server) receives it: the page may show a state
    before another subscriber has it."""
    _until(lambda: _mode(rig, "alpha") == "idle", what="alpha's state saying idle")


def _following(rig: Rig) -> None:
    """alpha follows the AUV (armed and told to, if it is not already)."""
    def go() -> bool:
        if _mode(rig, "alpha") == "follow":
            return True
        rig.observer.command("alpha", "arm", {})
        rig.observer.command("alpha", "follow", {})
        time.sleep(0.5)
        return _mode(rig, "alpha") == "follow"

    _until(go, 60.0, "alpha following")


def test_stop_button_and_escape_stop_the_boat(rig: Rig) -> None:
    page = rig.op
    _until(lambda: page.evaluate("() => zarco.selected()") == "alpha")
    page.wait_for_selector("#stop", state="visible")
    _following(rig)
    _text(page, "#mode", "t === 'follow'")
    t0 = _boat_t(rig, "alpha")
    page.click("#stop")
    _text(page, "#mode", "t === 'idle'", 10_000)
    _stopped(rig)
    # the reply to the page comes apart from the state (the page may show the
    # mode first)
    _text(page, "#cmd-result", "t.startsWith('stop: accepted by alpha, mode idle')")
    _until(lambda: _acks(rig, "alpha", "stop from shore:alice: accepted", t0),
           what="the boat's acknowledgement")
    # stopped is disarmed: the supervisor refuses to follow, and the page says why
    _text(page, "#armed", "t === 'disarmed'")
    page.click("#cmd-follow")
    _text(page, "#cmd-result", "t.startsWith('follow: REFUSED')")
    assert page.text_content("#cmd-result") == "follow: REFUSED: disarmed"
    assert _mode(rig, "alpha") == "idle"
    # arm and follow again from the buttons, then Escape
    page.click("#cmd-arm")
    _text(page, "#cmd-result", "t.startsWith('arm: accepted')")
    _text(page, "#armed", "t === 'armed'")
    page.click("#cmd-follow")
    _text(page, "#cmd-result", "t.startsWith('follow: accepted')")
    _text(page, "#mode", "t === 'follow'")
    # hold here, then return: the boat's modes, as the page shows them
    for button, mode in (("hold", "hold"), ("return", "return")):
        tb = _boat_t(rig, "alpha")
        page.click(f"#cmd-{button}")
        _text(page, "#cmd-result", f"t.startsWith('{button}: accepted by alpha, mode {mode}')")
        _until(lambda mode=mode, tb=tb: _shows(rig, page, mode, tb),
               what=f"the page showing alpha in {mode}")
    page.keyboard.press("Escape")
    _text(page, "#mode", "t === 'idle'", 10_000)
    _stopped(rig)
    # the boat's reply to the page (one per command; its event may be held back by
    # the supervisor's per-source event budget after hold and return in the same second)
    _text(page, "#cmd-result", "t.startsWith('stop: accepted by alpha, mode idle')")
    _text(page, "#armed", "t === 'disarmed'")
    # the disarm button: armed, then disarmed, as the boat's state says
    page.click("#cmd-arm")
    _text(page, "#armed", "t === 'armed'")
    page.click("#cmd-disarm")
    _text(page, "#cmd-result", "t.startsWith('disarm: accepted')")
    _text(page, "#armed", "t === 'disarmed'")
    _until(lambda: rig.observer.snapshot()["alpha"].state.get("armed") is False)


def test_a_refusal_shows_the_boats_reason(rig: Rig) -> None:
    page = rig.op
    # beta, the other vessel heard, from the selector
    _until(lambda: "beta" in page.eval_on_selector_all("#vessel option",
                                                       "os => os.map(o => o.value)"))
    page.select_option("#vessel", "beta")
    _text(page, "#stop", "t === 'STOP beta'")
    page.wait_for_selector("#commands", state="visible")
    _until(lambda: rig.observer.snapshot()["beta"].state.get("mode"), what="beta's state")
    _text(page, "#mode", f"t === {_mode(rig, 'beta')!r}")
    mode = _mode(rig, "beta")
    # the reference: what beta answers an operator's follow (it has no buoy feed)
    ref = rig.observer.command("beta", "follow", {})
    assert len(ref) == 1 and not ref[0].ok and ref[0].reason
    page.click("#cmd-follow")
    _text(page, "#cmd-result", "t.includes('REFUSED')")
    text = page.text_content("#cmd-result")
    assert text == f"follow: REFUSED: {ref[0].reason}", text
    assert page.locator("#cmd-result.bad").count() == 1
    assert _mode(rig, "beta") == mode  # refused: nothing changed
    page.select_option("#vessel", "alpha")


def test_a_viewer_sees_no_commands_and_sends_none(rig: Rig) -> None:
    page = rig.viewer
    _text(page, "#role", "t.startsWith('viewer')")
    _text(page, "#mode", "t !== '—'")
    assert not page.is_visible("#stop") and not page.is_visible("#commands")
    assert page.locator("button:visible", has_text="arm").count() == 0
    mode = _mode(rig, "alpha")
    t0 = _boat_t(rig, "alpha")
    page.keyboard.press("Escape")
    # the page server refuses a viewer's command itself (its own token, its own origin)
    status, body = page.evaluate("""async () => {
        const token = document.querySelector('meta[name=zarco-token]').content;
        const r = await fetch("/api/command", {method: "POST", headers: {"Content-Type":
          "application/json", "X-Zarco-Token": token},
          body: JSON.stringify({vessel: "alpha", name: "stop", args: {}})});
        return [r.status, await r.json()]; }""")
    assert status == 400 and "may not command" in body["reason"], body
    time.sleep(1.0)
    assert page.text_content("#cmd-result") == ""
    assert _mode(rig, "alpha") == mode
    # nothing acknowledged for anyone but the operator (whose earlier commands'
    # acknowledgements may still arrive)
    assert [a for a in _acks(rig, "alpha", "", t0) if "shore:alice" not in a] == []


class _Other(http.server.BaseHTTPRequestHandler):
    """A page of another origin that tries the page server's WebSocket and a command."""

    target = ""

    def do_GET(self) -> None:
        html = f"""<!doctype html><html><body><pre id=out>wait</pre><script>
        const out = document.getElementById("out");
        const ws = new WebSocket("ws://{self.target}/ws");
        ws.onopen = () => out.textContent = "OPEN";
        ws.onclose = (e) => out.textContent = "CLOSED " + e.code;
        fetch("http://{self.target}/api/command", {{method: "POST", mode: "no-cors",
          credentials: "include", headers: {{"Content-Type": "text/plain"}},
          body: JSON.stringify({{vessel: "alpha", name: "stop", args: {{}}}})}});
        </script></body></html>""".encode()
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.send_header("Content-Length", str(len(html)))
        self.end_headers()
        self.wfile.write(html)

    def log_message(self, *_a: Any) -> None:
        pass


def test_another_origin_gets_no_websocket_and_no_command(rig: Rig) -> None:
    op_ctx = rig.op.context
    host = rig.op_web.url.split("/")[2]
    # arm and follow, so that a stop would show
    _following(rig)
    t0 = _boat_t(rig, "alpha")
    # a page served from another port of this computer, in the operator's browser (its
    # cookie for 127.0.0.1 goes along: SameSite does not tell ports apart)
    _Other.target = host
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", free_port()), _Other)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        evil = op_ctx.new_page()
        evil.goto(f"http://127.0.0.1:{srv.server_address[1]}/")
        _text(evil, "#out", "t.startsWith('CLOSED')")
        assert evil.text_content("#out") == "CLOSED 1006"
        evil.close()
    finally:
        srv.shutdown()
    time.sleep(1.0)
    assert _mode(rig, "alpha") != "idle"  # not stopped
    assert _acks(rig, "alpha", "stop from", t0) == []
    # the same by hand: the cookie of a real session, another Origin
    cookie = next(c for c in op_ctx.cookies() if c["name"] == "zarco_web")
    token = rig.op.get_attribute('meta[name="zarco-token"]', "content")

    def post(headers: dict[str, str], body: bytes = b'{"vessel":"alpha","name":"stop"}'
             ) -> int:
        req = urllib.request.Request(f"http://{host}/api/command", data=body, method="POST",
                                     headers={"Content-Type": "application/json", **headers})
        try:
            with urllib.request.urlopen(req, timeout=10.0) as r:
                return int(r.status)
        except urllib.error.HTTPError as exc:
            return int(exc.code)

    me = f"http://{host}"
    ck = f"zarco_web={cookie['value']}"
    assert post({"Cookie": ck, "Origin": "http://evil.example", "X-Zarco-Token": token}) == 403
    assert post({"Cookie": ck, "Origin": me}) == 403                       # no token
    assert post({"Cookie": ck, "Origin": me, "X-Zarco-Token": "x" * 43}) == 403
    assert post({"Origin": me, "X-Zarco-Token": token}) == 403             # no session
    assert post({"Cookie": ck, "X-Zarco-Token": token}) == 403             # no Origin
    assert post({"Cookie": ck, "Origin": me, "X-Zarco-Token": token,
                 "Sec-Fetch-Site": "same-site"}) == 403
    assert post({"Cookie": ck, "Origin": me, "X-Zarco-Token": token, "Host": "evil.example"},
                ) == 421                                                   # DNS rebinding
    assert _mode(rig, "alpha") != "idle"
    # the WebSocket by hand: another Origin, or no session, is refused; the page's is not
    import websockets.sync.client as wsc
    from websockets.exceptions import InvalidStatus

    for headers in ({"Cookie": ck, "Origin": "http://evil.example"}, {"Origin": me}, {}):
        with pytest.raises(InvalidStatus) as exc:
            wsc.connect(f"ws://{host}/ws", additional_headers=headers, origin=None,
                        open_timeout=10.0).close()
        assert exc.value.response.status_code == 403
    with wsc.connect(f"ws://{host}/ws", additional_headers={"Cookie": ck}, origin=me,
                     open_timeout=10.0) as ws:
        hello = json.loads(ws.recv(timeout=10.0))
        assert hello["type"] == "hello" and "alpha" in hello["vessels"]
    # and a well-formed command from the page's origin, with its token: accepted
    assert post({"Cookie": ck, "Origin": me, "X-Zarco-Token": token}) == 200
    _until(lambda: _mode(rig, "alpha") == "idle")


def test_page_assets_are_the_packages_and_nothing_else(rig: Rig) -> None:
    host = rig.op_web.url.split("/")[2]
    static = Path(__file__).resolve().parents[1] / "zarco_tools/shore/web/static"
    for name in ("app.js", "map.js", "style.css"):
        with urllib.request.urlopen(f"http://{host}/static/{name}", timeout=10.0) as r:
            assert r.read() == (static / name).read_bytes()
            assert "default-src 'none'" in r.headers["Content-Security-Policy"]
    for bad in ("index.html", "..%2Fserver.py", "nothing.js"):
        with pytest.raises(urllib.error.HTTPError) as exc:
            urllib.request.urlopen(f"http://{host}/static/{bad}", timeout=10.0)
        assert exc.value.code == 404
    # nothing from elsewhere: every request the page made went to its own server
    reqs: list[str] = []
    page = rig.browser.new_context().new_page()
    page.on("request", lambda r: reqs.append(r.url))
    page.goto(rig.op_web.url)
    page.wait_for_function("() => zarco.connected && zarco.samples > 5")
    page.close()
    assert reqs and all(u.startswith(f"http://{host}/") or u.startswith(f"ws://{host}/")
                        for u in reqs), reqs
