"""Benchmark: ``zarco shore web`` with three simulated boats, a real browser.

    python tests/bench/web.py [--quick] [--runs N] [--seconds S] [--stops N]

Three boats are ``zarco sim config/scenarios/rectangle.toml --realtime`` in their
own processes (the real runtime and shore link, ``auth = "none"`` on loopback);
the page server is ``zarco shore web`` in its own process with a console
configuration naming the three; the page is open in the distribution's Chromium
(Playwright).  An independent zenoh client (this process) hears every state.

* page update latency: each ``state`` of the selected vessel from its arrival
  at the independent client (time.time()) to the moment the page's panel shows
  it (Date.now() after the DOM update), p50/p99 per run and pooled;
* stop latency: the STOP button clicked → the boat's reply on the page → the
  mode shown ``idle`` (the state that says so), per trial; the vessel is
  re-armed and resumed between trials;
* CPU of ``zarco shore web`` (process CPU time, all threads, from /proc) over
  each run with the page open, % of one core; and with no page open;
* bytes per vessel on the boat's link: the TCP payload the page server
  received from each boat (``ss -tip``, its own sockets), bytes/s and
  segments/s per vessel; and the WebSocket bytes/s per vessel to the page;
* the boat's own CPU: each boat's process CPU with the page server (and its
  page) connected, against the same boats with the console (``zarco shore
  status``) connected instead, alternated: what the web view costs the boat
  beyond a console (it must be nothing).

Progress on stderr; one JSON line of figures on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from shore_support import RECT, Boat, boats, free_port  # noqa: E402
from web_support import WebProcess, launch  # noqa: E402

from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient  # noqa: E402

VESSELS = ("v1", "v2", "v3")


def log(msg: str) -> None:
    print(f"[web bench] {msg}", file=sys.stderr, flush=True)


def pct(xs: list[float], q: float) -> float:
    if not xs:
        return float("nan")
    s = sorted(xs)
    return s[min(len(s) - 1, round(q / 100.0 * (len(s) - 1)))]


def cpu_s(pid: int) -> float:
    """User + system CPU time of a process, all its threads (s)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def tcp_received(port: int, pid: int) -> tuple[int, int]:
    """(bytes, segments) the process ``pid`` has received so far on its connections to
    ``port`` (what the boat listening there sent it: TCP payload)."""
    out = subprocess.run(["ss", "-tinpH", "state", "established", f"( dport = :{port} )"],
                         capture_output=True, text=True, check=True).stdout
    b = s = 0
    lines = out.splitlines()
    for head, info in zip(lines[::2], lines[1::2], strict=False):
        if f"pid={pid}," not in head:
            continue
        b += sum(int(x) for x in re.findall(r"bytes_received:(\d+)", info))
        s += sum(int(x) for x in re.findall(r"data_segs_in:(\d+)", info))
    return b, s


class Observer:
    """An independent zenoh client: the arrival time of every state."""

    def __init__(self, eps: list[str]) -> None:
        self.arrivals: dict[tuple[str, float], float] = {}
        self.lock = threading.Lock()

        def on_sample(v: str, kind: str, obj: dict[str, Any], _now: float) -> None:
            if kind == "state":
                with self.lock:
                    self.arrivals[(v, obj["t"])] = time.time()

        self.client = ShoreClient(ConsoleConfig([Credentials(e) for e in eps], user="bench"),
                                  on_sample=on_sample)
        deadline = time.monotonic() + 60.0
        while True:
            failed = self.client.connect()
            if not failed and len(self.client.wait_vessels(10.0, VESSELS[-1])) >= 3:
                break
            self.client.close()
            self.client.sessions = []
            if time.monotonic() > deadline:
                raise SystemExit(f"boats not heard: {failed}")
            time.sleep(1.0)

    def mode(self, v: str) -> str:
        return str(self.client.snapshot()[v].state.get("mode"))


def wait(pred: Any, timeout_s: float = 30.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got = pred()
        if got:
            return got
        time.sleep(0.05)
    raise SystemExit("timed out")


STOP_JS = """async () => {
  const mode = document.getElementById("mode");
  const res = document.getElementById("cmd-result");
  const t0 = performance.now();
  let tReply = null, tIdle = null;
  await new Promise((resolve) => {
    const obs = new MutationObserver(() => {
      if (tReply === null && res.textContent.startsWith("stop:")) tReply = performance.now();
      if (tIdle === null && mode.textContent === "idle") tIdle = performance.now();
      if (tReply !== null && tIdle !== null) { obs.disconnect(); resolve(); }
    });
    obs.observe(document.body, {subtree: true, childList: true, characterData: true});
    document.getElementById("stop").click();
    setTimeout(resolve, 10000);
  });
  return [tReply === null ? null : tReply - t0, tIdle === null ? null : tIdle - t0,
          res.textContent];
}"""


def run(args: argparse.Namespace) -> dict[str, Any]:
    from playwright.sync_api import sync_playwright

    tmp = Path(tempfile.mkdtemp(prefix="zarco-web-bench-"))
    ports = [free_port() for _ in VESSELS]
    eps = [f"tcp/127.0.0.1:{p}" for p in ports]
    bs = [Boat([f'runtime.shore.listen=["{ep}"]', f"runtime.shore.vessel={v}"], scenario=RECT,
               log=tmp / f"{v}.log") for v, ep in zip(VESSELS, eps, strict=True)]
    conf = tmp / "console.toml"
    conf.write_text(f'vessel = "{VESSELS[0]}"\nconnect = [' + ", ".join(f'"{e}"' for e in eps)
                    + "]\n")
    out: dict[str, Any] = {"vessels": len(VESSELS), "runs": args.runs,
                           "seconds_per_run": args.seconds}
    with boats(*bs):
        obs = Observer(eps)
        log("3 boats heard")
        lat_all: list[float] = []
        runs: list[dict[str, Any]] = []
        boat_cpu_web: list[float] = []
        boat_cpu_console: list[float] = []
        with sync_playwright() as p:
            browser = launch(p)
            for k in range(args.runs):
                # the console's turn: the boats' CPU with zarco shore status connected
                env = {**os.environ, "ZARCO_SHORE_CONFIG": str(conf)}
                con = subprocess.Popen([sys.executable, "-m", "zarco_runtime.cli", "shore",
                                        "status", "--plain"], stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL, cwd=ROOT, env=env)
                time.sleep(3.0)
                c0 = [cpu_s(b.pid) for b in bs]
                time.sleep(args.seconds)
                c1 = [cpu_s(b.pid) for b in bs]
                boat_cpu_console += [100.0 * (b - a) / args.seconds for a, b in zip(c0, c1,
                                                                                  strict=True)]
                con.terminate()
                con.wait(10)
                # the web's turn
                web = WebProcess(conf, free_port(), log=tmp / f"web{k}.log").start()
                time.sleep(2.0)
                w0 = cpu_s(web.pid)
                time.sleep(args.seconds / 2)
                idle_cpu = 100.0 * (cpu_s(web.pid) - w0) / (args.seconds / 2)
                page = browser.new_context(viewport={"width": 1400, "height": 850}).new_page()
                page.goto(web.url)
                page.wait_for_function("() => zarco.connected && zarco.samples > 20")
                time.sleep(2.0)
                page.evaluate("() => { zarco.renders.length = 0; zarco.bytes = 0; }")
                w0, b0 = cpu_s(web.pid), [cpu_s(b.pid) for b in bs]
                n0 = [tcp_received(pt, web.pid) for pt in ports]
                t0 = time.monotonic()
                time.sleep(args.seconds)
                dt = time.monotonic() - t0
                w1, b1 = cpu_s(web.pid), [cpu_s(b.pid) for b in bs]
                n1 = [tcp_received(pt, web.pid) for pt in ports]
                renders, ws_bytes = page.evaluate("() => [zarco.renders, zarco.bytes]")
                boat_cpu_web += [100.0 * (b - a) / dt for a, b in zip(b0, b1, strict=True)]
                with obs.lock:
                    arr = dict(obs.arrivals)
                lat = [ms / 1000.0 - arr[(v, t)] for v, t, ms in renders if (v, t) in arr]
                lat_ms = [1000.0 * x for x in lat]
                lat_all += lat_ms
                link = [((b[0] - a[0]) / dt, (b[1] - a[1]) / dt) for a, b in zip(n0, n1,
                                                                              strict=True)]
                r = {"latency_p50_ms": round(pct(lat_ms, 50), 1),
                     "latency_p99_ms": round(pct(lat_ms, 99), 1),
                     "states_shown_hz": round(len(renders) / dt, 2), "matched": len(lat_ms),
                     "web_cpu_pct": round(100.0 * (w1 - w0) / dt, 1),
                     "web_cpu_no_page_pct": round(idle_cpu, 1),
                     "link_bytes_per_s_per_vessel": [round(x[0]) for x in link],
                     "link_segments_per_s_per_vessel": [round(x[1], 1) for x in link],
                     "websocket_bytes_per_s_per_vessel": round(ws_bytes / dt / len(VESSELS))}
                log(f"run {k + 1}: {r}")
                runs.append(r)
                if k == args.runs - 1:
                    out["stops"] = stops(page, obs, args.stops)
                page.context.close()
                web.stop()
            browser.close()
        obs.client.close()
    out["runs_detail"] = runs
    out["latency_p50_ms"] = round(pct(lat_all, 50), 1)
    out["latency_p99_ms"] = round(pct(lat_all, 99), 1)
    out["latency_samples"] = len(lat_all)
    out["web_cpu_pct_median"] = round(statistics.median(r["web_cpu_pct"] for r in runs), 1)
    out["web_cpu_no_page_pct_median"] = round(statistics.median(
        r["web_cpu_no_page_pct"] for r in runs), 1)
    per_vessel = [x for r in runs for x in r["link_bytes_per_s_per_vessel"]]
    out["link_bytes_per_s_per_vessel_median"] = round(statistics.median(per_vessel))
    out["websocket_bytes_per_s_per_vessel_median"] = round(statistics.median(
        r["websocket_bytes_per_s_per_vessel"] for r in runs))
    out["boat_cpu_pct_with_console"] = round(statistics.median(boat_cpu_console), 2)
    out["boat_cpu_pct_with_web"] = round(statistics.median(boat_cpu_web), 2)
    out["boat_cpu_ratio_web_to_console"] = round(statistics.median(boat_cpu_web)
                                                 / statistics.median(boat_cpu_console), 3)
    return out


def stops(page: Any, obs: Observer, n: int) -> dict[str, Any]:
    """STOP clicked on the page → reply shown, → mode idle shown (ms), ``n`` trials."""
    v = VESSELS[0]
    reply, idle = [], []
    for i in range(n):
        obs.client.command(v, "arm", {})
        r = obs.client.command(v, "resume", {})
        if not r or not r[0].ok:
            log(f"resume refused: {r[0].reason if r else 'no reply'}")
        wait(lambda: obs.mode(v) == "lines")
        page.wait_for_function("() => document.getElementById('mode').textContent === 'lines'")
        time.sleep(0.5 + 0.37 * (i % 3))  # not in step with the 5 Hz state
        t_reply, t_idle, text = page.evaluate(STOP_JS)
        if t_reply is None or t_idle is None:
            raise SystemExit(f"stop trial {i}: {text}")
        reply.append(t_reply)
        idle.append(t_idle)
        log(f"stop {i + 1}: reply {t_reply:.0f} ms, idle shown {t_idle:.0f} ms")
    return {"trials": n, "reply_p50_ms": round(pct(reply, 50)),
            "reply_max_ms": round(max(reply)), "idle_shown_p50_ms": round(pct(idle, 50)),
            "idle_shown_max_ms": round(max(idle)),
            "idle_within_1s": sum(x <= 1000.0 for x in idle)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="1 run of 20 s, 3 stops")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=40.0)
    ap.add_argument("--stops", type=int, default=10)
    args = ap.parse_args()
    if args.quick:
        args.runs, args.seconds, args.stops = 1, 20.0, 3
    print(json.dumps(run(args)))


if __name__ == "__main__":
    main()
