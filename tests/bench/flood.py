"""Benchmark: floods from shore cost bandwidth, not control.

    python tests/bench/flood.py [--rtcm N] [--rtcm-bytes B] [--commands N]
                                [--clients K] [--runs R] [--quiet-s S]

The boat is the real runtime as on the vessel, ``zarco run`` under ``zarco
hil`` (the simulator behind pseudo-terminals, real time) on the rectangle
mission, with the shore link on (``auth = "usrpwd"``) and systemd's watchdog
protocol (a ``NOTIFY_SOCKET`` datagram socket here, ``WATCHDOG_USEC`` = 2 s:
the runtime pings every second only while its control loop ticks and its
supervisor evaluates failsafes).

After the mission has started and a quiet spell (``--quiet-s``), ``--clients``
operator clients, each its own process with its own zenoh session, flood at
once: together ``--rtcm`` RTCM samples of ``--rtcm-bytes`` (valid frames,
through a declared publisher that blocks rather than drops), ``--commands``
commands sent without waiting for the replies (``thrust``, refused "not in
manual mode", and hostile payloads), and operator heartbeats as fast as they
go for as long as the rest lasts.  On the boat the clients are other
computers; here they share its two cores, so they run at ``nice 10``
(``--client-nice 0``: on equal terms with the runtime).  A probe operator (another process) sends
its heartbeat at 1 Hz and one command every 0.5 s throughout, timing each
reply.

Figures, per run and pooled (worst of the runs):

* ``control_hz_mean``: control ticks per second over the flood, from the
  runtime's 1 Hz status (its ticks counter over wall time);
  ``control_hz_min``: the same over the slowest 2 s window of the flood;
* ``runtime_cpu_quiet_pct`` / ``runtime_cpu_flood_pct``: the runtime process's
  CPU (all threads, % of one core) before and during the flood;
* ``tick_jitter_p99_ms`` / ``tick_jitter_max_ms``: |period − 50 ms| of the
  control loop over the whole run (its own histogram, written at exit);
* ``watchdog_gap_max_s``: the longest time between two WATCHDOG=1 pings;
* ``rtt_p50_ms`` / ``rtt_p99_ms`` / ``rtt_max_ms``: the probe's command round
  trip during the flood; ``probe_no_reply``: its commands left unanswered;
* ``failsafes``, ``modes``: every failsafe and mode the vessel went through
  (from its status), ``mission_aborted``: whether it ever left ``lines``;
* the flood's own counts: samples and commands sent, replies received (one per
  command expected), and the link's counters (RTCM dropped over the budget,
  commands answered "busy", heartbeats coalesced).

Targets: control ≥ 19.5 Hz, watchdog gap ≤ 0.6 s beyond its 1 s period (so
≤ 1.6 s between pings), no failsafe, no mission aborted.

Progress on stderr; one JSON line of figures on stdout.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

WATCHDOG_USEC = 2_000_000
RECT = ROOT / "config" / "scenarios" / "rectangle.toml"


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def pct(xs: list[float], q: float) -> float | None:
    s = sorted(xs)
    if not s:
        return None
    return s[min(len(s) - 1, max(0, round(q / 100.0 * (len(s) - 1))))]


# ------------------------------------------------------------------ clients


def _session(ep: str, user: str, password: str) -> Any:
    import zenoh

    from zarco_runtime.links.shore.zenoh_config import client_config

    return zenoh.open(zenoh.Config.from_json5(json.dumps(
        client_config(ep, user=user, password=password))))


def flood_client(a: argparse.Namespace) -> None:
    """One flooding operator (its own process): prints one JSON line."""
    import zenoh

    os.nice(a.client_nice)
    from drivers.rtcm import frame

    s = _session(a.endpoint, a.user, a.password)
    key = f"zarco/{a.vessel}"
    frames = b""
    k = 0
    while len(frames) + 1029 <= a.rtcm_bytes:
        frames += frame(bytes((0x3E, 0xD0)) + bytes([k % 256]) * 1000)
        k += 1
    sample = frames + bytes(a.rtcm_bytes - len(frames))
    rtcm = s.declare_publisher(f"{key}/rtcm", congestion_control=zenoh.CongestionControl.BLOCK)
    hb = s.declare_publisher(f"{key}/operator")
    replies: dict[str, int] = {"ok": 0, "refused": 0, "busy": 0, "bad": 0, "error": 0}
    lock = threading.Lock()
    done = threading.Event()
    out: dict[str, Any] = {"user": a.user}

    def on_reply(r: Any) -> None:
        with lock:
            if r.ok is None:
                replies["error"] += 1
                return
            d = json.loads(r.ok.payload.to_bytes())
            reason = str(d.get("reason", ""))
            kind = ("ok" if d.get("ok") else "busy" if reason.startswith("busy")
                    else "bad" if reason.startswith("bad request") else "refused")
            replies[kind] += 1

    hostile = [b"[" * 30000, b"\xff\xfe", b'{"u1": 1e999, "u2": 0}', b'{"u1": "1e2", "u2": 0}',
               b"{" * 100]

    def commands() -> None:
        for i in range(a.commands):
            payload = hostile[i % len(hostile)] if i % 10 == 9 else b'{"u1": 0, "u2": 0}'
            s.get(f"{key}/cmd/thrust", on_reply, payload=payload, timeout=30.0)
        out["commands_sent"] = a.commands

    def corrections() -> None:
        for _ in range(a.rtcm):
            rtcm.put(sample)
        out["rtcm_sent"] = a.rtcm

    def heartbeats() -> None:
        n = 0
        end = time.monotonic() + a.min_s
        while not done.is_set() or time.monotonic() < end:
            if not a.heartbeat_flood:
                break
            hb.put(json.dumps({"t": time.time(), "user": a.user}))
            n += 1
            if n % 64 == 0:
                time.sleep(0.001)  # lets the other threads of this client run
        out["heartbeats_sent"] = n

    t0 = time.monotonic()
    threads = [threading.Thread(target=f) for f in (commands, corrections)]
    hbt = threading.Thread(target=heartbeats)
    for t in [*threads, hbt]:
        t.start()
    for t in threads:
        t.join()
    while a.heartbeat_flood and time.monotonic() - t0 < a.min_s:
        time.sleep(0.05)
    out["flood_s"] = round(time.monotonic() - t0, 3)
    deadline = time.monotonic() + 40.0
    while time.monotonic() < deadline:
        with lock:
            if sum(replies.values()) >= a.commands:
                break
        time.sleep(0.05)
    done.set()
    hbt.join()
    out["replies"] = dict(replies)
    out["replies_total"] = sum(replies.values())
    s.close()
    print(json.dumps(out), flush=True)


def probe_client(a: argparse.Namespace) -> None:
    """The probe: heartbeat 1 Hz, a command every 0.5 s, timed, until stdin closes."""
    s = _session(a.endpoint, a.user, a.password)
    key = f"zarco/{a.vessel}"
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    health: dict[str, Any] = {}
    s.declare_subscriber(f"{key}/health",
                         lambda smp: health.update(json.loads(smp.payload.to_bytes())))
    next_hb = 0.0
    while not stop.is_set():
        now = time.monotonic()
        if now >= next_hb:
            s.put(f"{key}/operator", json.dumps({"t": time.time(), "user": a.user}))
            next_hb = now + 1.0
        t0 = time.monotonic()
        got = [r for r in s.get(f"{key}/cmd/thrust", payload='{"u1": 0, "u2": 0}',
                                timeout=5.0) if r.ok is not None]
        rtt = time.monotonic() - t0
        print(json.dumps({"wall": time.time(), "rtt_s": rtt if got else None}), flush=True)
        stop.wait(max(0.0, 0.5 - rtt))
    print(json.dumps({"link": health.get("link", {})}), flush=True)
    s.close()


# ---------------------------------------------------------------------- boat


class Watchdog:
    """The notify socket: the time of every WATCHDOG=1."""

    def __init__(self, path: str) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(path)
        self.sock.settimeout(0.2)
        self.pings: list[float] = []
        self.other: list[str] = []
        self.stop = threading.Event()
        threading.Thread(target=self._run, daemon=True).start()

    def _run(self) -> None:
        while not self.stop.is_set():
            try:
                data = self.sock.recv(4096).decode()
            except TimeoutError:
                continue
            if data == "WATCHDOG=1":
                self.pings.append(time.monotonic())
            else:
                self.other.append(data)


def _runtime_pids(run_dir: Path) -> list[int]:
    """The ``zarco run`` that ``zarco hil`` started for ``run_dir`` (its own session:
    a signal to the rig does not reach it)."""
    want = str(run_dir / "zarco.toml").encode()
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            with contextlib.suppress(OSError):
                if want in (d / "cmdline").read_bytes():
                    pids.append(int(d.name))
    return pids


def _cpu_s(pids: list[int]) -> float:
    """CPU time (user + system, all threads) of ``pids`` so far (s)."""
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for pid in pids:
        with contextlib.suppress(OSError):
            f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            total += int(f[11]) + int(f[12])
    return total / tick


def _stop(hil: subprocess.Popen[bytes], run_dir: Path) -> None:
    """End the runtime (SIGTERM: zero thrust, exit 0), then the rig after it."""
    for pid in _runtime_pids(run_dir):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
    try:
        hil.wait(60)
    except subprocess.TimeoutExpired:
        hil.send_signal(signal.SIGTERM)
        try:
            hil.wait(30)
        except subprocess.TimeoutExpired:
            hil.kill()
            hil.wait()
    for pid in _runtime_pids(run_dir):  # still there: it did not stop on SIGTERM
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def _status_lines(path: Path) -> list[dict[str, Any]]:
    out = []
    if path.exists():
        for ln in path.read_text().splitlines():
            with contextlib.suppress(ValueError):  # a line being written
                out.append(json.loads(ln))
    return out


def one_run(a: argparse.Namespace, k: int) -> dict[str, Any]:
    from shore_support import free_port, write_users

    tmp = Path(tempfile.mkdtemp(prefix="zarco-flood-"))
    users = {f"op{i}": f"pw{i}" for i in range(a.clients)} | {"probe": "pw-probe"}
    write_users(tmp / "users", users)
    ep = f"tcp/127.0.0.1:{free_port()}"
    wd = Watchdog(str(tmp / "notify"))
    run_dir = tmp / "run"
    ops = json.dumps(sorted(users))
    cmd = [sys.executable, "-m", "zarco_runtime.cli", "hil", str(RECT), "-q",
           "--run-dir", str(run_dir), "--duration", str(a.duration_s),
           "--set", "runtime.shore.enabled=true", "--set", "runtime.shore.vessel=flood",
           "--set", f'runtime.shore.listen=["{ep}"]', "--set", 'runtime.shore.auth="usrpwd"',
           "--set", f'runtime.shore.users_file="{tmp / "users"}"',
           "--set", f"runtime.shore.operators={ops}",
           "--set", "runtime.failsafe.link_lost_s=10"]
    env = {**os.environ, "NOTIFY_SOCKET": str(tmp / "notify"),
           "WATCHDOG_USEC": str(WATCHDOG_USEC), "PYTHONUNBUFFERED": "1"}
    env.pop("WATCHDOG_PID", None)
    hil = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                           stderr=(tmp / "hil.log").open("wb"))
    status = run_dir / "status.jsonl"
    log(f"run {k}: zarco hil (pid {hil.pid}) in {tmp}")
    try:
        deadline = time.monotonic() + 90.0
        while not any(ln.get("mode") == "lines" for ln in _status_lines(status)):
            if time.monotonic() > deadline or hil.poll() is not None:
                raise RuntimeError(f"the mission never started; see {tmp}/hil.log")
            time.sleep(0.5)
        me = [sys.executable, str(Path(__file__).resolve())]
        base = ["--endpoint", ep, "--vessel", "flood"]
        probe = subprocess.Popen([*me, "--probe", *base, "--user", "probe",
                                  "--password", "pw-probe"], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, text=True, cwd=ROOT)
        log(f"run {k}: mission under way; quiet for {a.quiet_s:g} s")
        pids = _runtime_pids(run_dir)
        c0, t0 = _cpu_s(pids), time.monotonic()
        time.sleep(a.quiet_s)
        c1, t1 = _cpu_s(pids), time.monotonic()
        cpu_quiet = round(100.0 * (c1 - c0) / (t1 - t0), 1)
        w0 = time.time()
        per = [(a.rtcm + i) // a.clients for i in range(a.clients)]
        cper = [(a.commands + i) // a.clients for i in range(a.clients)]
        floods = [subprocess.Popen([*me, "--flood", *base, "--user", f"op{i}",
                                    "--password", f"pw{i}", "--rtcm", str(per[i]),
                                    "--rtcm-bytes", str(a.rtcm_bytes),
                                    "--commands", str(cper[i]), "--min-s", str(a.min_s),
                                    "--client-nice", str(a.client_nice),
                                    *([] if a.heartbeat_flood else ["--no-heartbeat-flood"])],
                                   stdout=subprocess.PIPE, text=True, cwd=ROOT)
                  for i in range(a.clients)]
        log(f"run {k}: flooding: {a.rtcm} × {a.rtcm_bytes} B RTCM, {a.commands} commands, "
            f"heartbeats, from {a.clients} clients")
        results = []
        for f in floods:
            outp, _ = f.communicate(timeout=300)
            results.append(json.loads(outp.strip().splitlines()[-1]))
        w1 = w0 + max(r["flood_s"] for r in results)
        cpu_flood = round(100.0 * (_cpu_s(pids) - c1) / (time.monotonic() - t1), 1)
        log(f"run {k}: flood sent in {w1 - w0:.1f} s; quiet for {a.quiet_s:g} s")
        time.sleep(a.quiet_s)
        assert probe.stdin is not None and probe.stdout is not None
        probe.stdin.close()  # the probe's signal to stop
        pout = probe.stdout.read()
        probe.wait(30)
    finally:
        _stop(hil, run_dir)
        wd.stop.set()
    lines = _status_lines(status)
    snaps = [ln for ln in lines if ln.get("kind") == "status" and not ln.get("final")]
    final = next((ln for ln in reversed(lines) if ln.get("final")), {})
    # control rate over the flood, between consecutive status snapshots
    # (the control loop keeps an absolute schedule: a late tick is followed by
    # quick ones, so a one-second window after a stall reads above 20 Hz)
    inside = [sn for sn in snaps if w0 - 1.0 <= sn["wall"] <= w1 + 1.0]
    rates = []
    for p, q in itertools.pairwise(inside[::2]):  # windows of about 2 s
        rates.append((q["counters"]["control_ticks"] - p["counters"]["control_ticks"])
                     / (q["wall"] - p["wall"]))
    span = (inside[-1]["counters"]["control_ticks"] - inside[0]["counters"]["control_ticks"]) \
        / (inside[-1]["wall"] - inside[0]["wall"]) if len(inside) > 1 else None
    hist = final.get("control", {}).get("period_jitter_hist", [])
    jit = []
    for i, n in enumerate(hist):
        jit += [i * 0.05] * n  # bins of 50 µs, in ms
    gaps = [b - a_ for a_, b in zip(wd.pings, wd.pings[1:], strict=False)]
    probes = [json.loads(ln) for ln in pout.splitlines() if ln.strip()]
    link = next((p["link"] for p in probes if "link" in p), {})
    probes = [p for p in probes if "wall" in p]
    during = [p for p in probes if w0 <= p["wall"] <= w1 + 2.0]
    rtts = [p["rtt_s"] * 1000 for p in during if p["rtt_s"] is not None]
    failsafes = sorted({f for s in snaps for f in s.get("failsafes", [])})
    started = next(i for i, s in enumerate(snaps) if s.get("mode") == "lines")
    modes = sorted({s.get("mode") for s in snaps[started:]})
    restarts = {n: c.get("restarts", 0) for n, c in snaps[-1].get("components", {}).items()
                if isinstance(c, dict)} if snaps else {}
    return {
        "control_hz_min": round(min(rates), 2) if rates else None,
        "control_hz_mean": round(span, 2) if span is not None else None,
        "runtime_cpu_quiet_pct": cpu_quiet, "runtime_cpu_flood_pct": cpu_flood,
        "tick_jitter_p99_ms": pct(jit, 99), "tick_jitter_max_ms": max(jit) if jit else None,
        "watchdog_gap_max_s": round(max(gaps), 3) if gaps else None,
        "watchdog_pings": len(wd.pings),
        "rtt_p50_ms": round(pct(rtts, 50) or 0, 1), "rtt_p99_ms": round(pct(rtts, 99) or 0, 1),
        "rtt_max_ms": round(max(rtts), 1) if rtts else None,
        "probe_commands": len(during),
        "probe_no_reply": sum(1 for p in during if p["rtt_s"] is None),
        "failsafes": failsafes, "modes": modes, "mission_aborted": modes != ["lines"],
        "restarts": restarts,
        "flood_s": round(w1 - w0, 2),
        "rtcm_sent": sum(r["rtcm_sent"] for r in results),
        "commands_sent": sum(r["commands_sent"] for r in results),
        "replies": {k_: sum(r["replies"][k_] for r in results) for k_ in results[0]["replies"]},
        "heartbeats_sent": sum(r["heartbeats_sent"] for r in results),
        "link": link,
        "run_dir": str(tmp),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rtcm", type=int, default=1000)
    ap.add_argument("--rtcm-bytes", type=int, default=16384)
    ap.add_argument("--commands", type=int, default=10000)
    ap.add_argument("--clients", type=int, default=3)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--quiet-s", type=float, default=10.0)
    ap.add_argument("--client-nice", type=int, default=10,
                    help="niceness of the flooding clients: on the boat they are other "
                    "computers, here they share its cores (0: compete on equal terms)")
    ap.add_argument("--min-s", type=float, default=0.0,
                    help="flood heartbeats for at least this long (s)")
    ap.add_argument("--no-heartbeat-flood", dest="heartbeat_flood", action="store_false",
                    help="the flooding clients send no heartbeats")
    ap.add_argument("--duration-s", type=float, default=240.0,
                    help="zarco hil's --duration (the run ends earlier, once measured)")
    ap.add_argument("--flood", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--probe", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--endpoint", help=argparse.SUPPRESS)
    ap.add_argument("--vessel", help=argparse.SUPPRESS)
    ap.add_argument("--user", help=argparse.SUPPRESS)
    ap.add_argument("--password", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.flood:
        flood_client(a)
        return
    if a.probe:
        probe_client(a)
        return
    runs = [one_run(a, k) for k in range(1, a.runs + 1)]
    for r in runs:
        log(json.dumps(r))
    worst = {
        "runs": len(runs),
        "control_hz_min": min(r["control_hz_min"] or 0.0 for r in runs),
        "control_hz_mean": min(r["control_hz_mean"] or 0.0 for r in runs),
        "tick_jitter_p99_ms": max(r["tick_jitter_p99_ms"] or 0.0 for r in runs),
        "tick_jitter_max_ms": max(r["tick_jitter_max_ms"] or 0.0 for r in runs),
        "watchdog_gap_max_s": max(r["watchdog_gap_max_s"] or 99.0 for r in runs),
        "rtt_p50_ms": max(r["rtt_p50_ms"] for r in runs),
        "rtt_p99_ms": max(r["rtt_p99_ms"] for r in runs),
        "rtt_max_ms": max(r["rtt_max_ms"] or 0.0 for r in runs),
        "probe_no_reply": sum(r["probe_no_reply"] for r in runs),
        "failsafes": sorted({f for r in runs for f in r["failsafes"]}),
        "mission_aborted": any(r["mission_aborted"] for r in runs),
        "per_run": runs,
    }
    print(json.dumps(worst))


if __name__ == "__main__":
    main()
