"""Benchmark: the shore link over zenoh on loopback, against simulated boats.

    python tests/bench/shore.py [--quick] [--cpu-pairs N] [--cpu-s S] [--base COMMIT]

Every boat is ``zarco sim config/scenarios/rectangle.toml --realtime`` in its
own process (the real runtime, its real shore link); the clients are real
zenoh sessions in this process.

* telemetry latency: ``state`` (5 Hz) from the boat's publication (its ``t``,
  UTC, stamped when the object is built) to its arrival here, p50/p99, one run
  per ``auth`` mode (none, usrpwd, mtls);
* command round trip: ``cmd/thrust`` queries (refused: "not in manual mode",
  so the mission goes on) from the console's ``get`` to the boat's reply,
  p50/p99;
* link loss → failsafe: the operator's heartbeat (2 Hz) stops; the time from
  the last heartbeat to the boat's "mode hold" event (boat UTC), and its
  excess over ``failsafe.link_lost_s``;
* commands accepted from viewers or unauthenticated clients (must be 0):
  a viewer's queries (replies, and acknowledgements the boat published), and
  sessions opened with no or wrong credentials;
* CPU of the shore link at nominal rates: process CPU time (all threads, from
  /proc) over the same real-time window of the same scenario, with the link
  (one console subscribed to everything, heartbeat 1 Hz) and without it,
  alternated; the difference in % of one core;
* simulation speed with the shore link disabled: ``zarco sim`` rectangle on
  the virtual clock, this tree against the base commit (the merge base with
  main, unpacked aside), alternated, same seeds: the ratio of median speed-ups.

Progress on stderr; one JSON line of figures on stdout.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
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

import zenoh  # noqa: E402
from shore_support import (  # noqa: E402
    RECT,
    Boat,
    Pki,
    boats,
    free_port,
    write_users,
)

from zarco_runtime.links.shore.zenoh_config import client_config  # noqa: E402
from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient  # noqa: E402

LINK_LOST_S = 3.0
TICK = os.sysconf("SC_CLK_TCK")


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    if not s:
        return float("nan")
    k = min(len(s) - 1, max(0, round(q / 100.0 * (len(s) - 1))))
    return s[k]


def ms(x: float) -> float:
    return round(1000.0 * x, 2)


def cpu_s(pid: int) -> float:
    """User + system CPU time of a process, all its threads (s)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def _connect(cred: Credentials, user: str, hz: float = 1.0, timeout_s: float = 30.0
             ) -> ShoreClient:
    deadline = time.monotonic() + timeout_s
    while True:
        c = ShoreClient(ConsoleConfig([cred], user=user, heartbeat_hz=hz))
        if not c.connect():
            return c
        c.close()
        if time.monotonic() > deadline:
            raise RuntimeError(f"cannot connect to {cred.endpoint}")
        time.sleep(0.2)


def _wait(c: ShoreClient, pred: Any, timeout_s: float = 30.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        v = c.snapshot().get("zarco")
        if v is not None and v.state and pred(v):
            return v.state
        time.sleep(0.05)
    raise RuntimeError("the boat never got there")


def link_run(auth: str, tmp: Path, seconds: float, n_cmds: int) -> dict[str, Any]:
    """One boat with ``auth``: latency, round trips, security, link loss."""
    port = free_port()
    proto = "tls" if auth == "mtls" else "tcp"
    ep = f"{proto}/127.0.0.1:{port}"
    sets = [f'runtime.shore.listen=["{ep}"]', f'runtime.shore.auth="{auth}"',
            f"runtime.failsafe.link_lost_s={LINK_LOST_S}"]
    op = view = Credentials(ep)
    bad: list[dict[str, Any]] = []
    if auth == "usrpwd":
        users = write_users(tmp / f"users-{auth}", {"alice": "a-pw", "bob": "b-pw"})
        sets += [f'runtime.shore.users_file="{users}"', 'runtime.shore.operators=["alice"]',
                 'runtime.shore.viewers=["bob"]']
        op, view = Credentials(ep, "alice", "a-pw"), Credentials(ep, "bob", "b-pw")
        bad = [client_config(ep), client_config(ep, user="alice", password="guess"),
               client_config(ep, user="eve", password="a-pw")]
    elif auth == "mtls":
        pki = Pki(tmp / "pki")
        rogue = Pki(tmp / "rogue", "rogue-ca")
        bc, bk = pki.issue("boat")
        sets += ['runtime.shore.auth="mtls"', f'runtime.shore.cert_file="{bc}"',
                 f'runtime.shore.key_file="{bk}"', f'runtime.shore.ca_file="{pki.ca_file}"',
                 'runtime.shore.operators=["alice"]', 'runtime.shore.viewers=["bob"]']
        a, b = pki.issue("alice"), pki.issue("bob")
        op = Credentials(ep, cert_file=a[0], key_file=a[1], ca_file=pki.ca_file)
        view = Credentials(ep, cert_file=b[0], key_file=b[1], ca_file=pki.ca_file)
        fake = rogue.issue("alice")
        bad = [client_config(ep, ca_file=pki.ca_file),
               client_config(ep, cert_file=fake[0], key_file=fake[1], ca_file=pki.ca_file),
               client_config(f"tcp/127.0.0.1:{port}")]
    out: dict[str, Any] = {"auth": auth}
    lat: list[float] = []
    stamps: list[float] = []
    lock = threading.Lock()

    def on_sample(_v: str, kind: str, obj: dict[str, Any], _now: float) -> None:
        if kind == "state":
            with lock:
                lat.append(time.time() - float(obj["t"]))
                stamps.append(float(obj["t"]))

    with boats(Boat(sets, log=tmp / f"boat-{auth}.log")):
        c = _connect(op, "alice", hz=2.0)
        c.on_sample = on_sample
        try:
            _wait(c, lambda v: v.state["mode"] == "lines")
            c.start_heartbeat(["zarco"])
            with lock:
                lat.clear()
                stamps.clear()
            rtt: list[float] = []
            t_end = time.monotonic() + seconds
            period = seconds / max(1, n_cmds)
            while time.monotonic() < t_end or len(rtt) < n_cmds:
                r = c.command("zarco", "thrust", {"u1": 10.0, "u2": 10.0})
                if len(r) != 1 or r[0].ok or r[0].reason != "not in manual mode":
                    raise RuntimeError(f"unexpected reply {r}")
                rtt.append(r[0].rtt_s)
                time.sleep(period)
            with lock:
                out["latency_samples"] = list(lat)
                out["state_intervals"] = [b - a for a, b in itertools.pairwise(stamps)
                                          if b > a]
            out["rtt"] = rtt
            # security: a viewer's commands, unauthenticated sessions
            if auth != "none":
                acks0 = len([e for e in c.snapshot()["zarco"].events if e["kind"] == "ack"])
                v = _connect(view, "bob")
                replies = 0
                try:
                    for i in range(30):
                        name, args = [("stop", {}), ("mode", {"mode": "idle"}),
                                      ("mission", {"waypoints": [[41.185, -8.705],
                                                                 [41.186, -8.705]]})][i % 3]
                        replies += len(v.command("zarco", name, args, timeout_s=0.5))
                finally:
                    v.close()
                time.sleep(1.0)
                acks1 = len([e for e in c.snapshot()["zarco"].events if e["kind"] == "ack"])
                connected = 0
                for cfg in bad * 5:
                    try:
                        s = zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))
                    except zenoh.ZError:
                        continue
                    connected += 1
                    s.close()
                out["security"] = {
                    "viewer_commands": 30, "viewer_replies": replies,
                    "acks_during_viewer_phase": acks1 - acks0,
                    "mode_after": c.snapshot()["zarco"].state["mode"],
                    "unauthenticated_attempts": len(bad) * 5,
                    "unauthenticated_connected": connected}
            # link loss
            c.stop_heartbeat()
            t_last = c.last_heartbeat
            assert t_last is not None
            _wait(c, lambda v: any(e["kind"] == "mode" and "link_lost" in e["text"]
                                   for e in v.events), timeout_s=LINK_LOST_S + 10.0)
            ev = next(e for e in c.snapshot()["zarco"].events
                      if e["kind"] == "mode" and "link_lost" in e["text"])
            out["link_loss_action_s"] = ev["t"] - t_last
            out["link_loss_mode"] = "hold" if "mode hold" in ev["text"] else ev["text"]
        finally:
            c.close()
    return out


def cpu_run(with_link: bool, seconds: float, tmp: Path, k: int) -> float:
    """CPU seconds the boat process used over ``seconds`` of real time."""
    port = free_port()
    args = [sys.executable, "-m", "zarco_runtime.cli", "sim", str(RECT), "--realtime", "-q",
            "--set", "scenario.max_duration_s=100000"]
    if with_link:
        args += ["--set", "runtime.shore.enabled=true", "--set",
                 f'runtime.shore.listen=["tcp/127.0.0.1:{port}"]']
    with (tmp / f"cpu-{k}-{int(with_link)}.log").open("wb") as fh:
        p = subprocess.Popen(args, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT)
    c = None
    try:
        if with_link:  # one console watching everything, with its heartbeat
            c = _connect(Credentials(f"tcp/127.0.0.1:{port}"), "alice")
            c.start_heartbeat(["zarco"])
        time.sleep(6.0)  # start-up (imports, first fixes) is not measured
        c0 = cpu_s(p.pid)
        time.sleep(seconds)
        c1 = cpu_s(p.pid)
        if c is not None and c.received < seconds * 5:
            raise RuntimeError(f"console received only {c.received} samples")
        return c1 - c0
    finally:
        if c is not None:
            c.close()
        p.terminate()
        p.wait(20)


SIM_CODE = """
import json, sys, time
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario
scn = load_scenario(sys.argv[1], ["mission.speed_mps=1.0"], int(sys.argv[2]))
c0 = time.process_time()
r = run_scenario(scn).report
cpu = time.process_time() - c0
print(json.dumps({"speedup": r["speedup"], "speedup_cpu": round(r["sim_seconds"] / cpu, 1),
                  "sim_seconds": r["sim_seconds"], "xtrack_rms_m": r["xtrack_rms_m"]}))
"""


def sim_speed(tree: Path, seed: int) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run([sys.executable, "-c", SIM_CODE,
                          str(tree / "config" / "scenarios" / "rectangle.toml"), str(seed)],
                         capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(),
                         timeout=600)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--link-s", type=float, default=40.0, help="seconds of telemetry per auth")
    ap.add_argument("--cmds", type=int, default=150, help="commands per auth mode")
    ap.add_argument("--cpu-pairs", type=int, default=3)
    ap.add_argument("--cpu-s", type=float, default=40.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--base", default="", help="base commit (default: merge base with main)")
    ap.add_argument("--sim-reps", type=int, default=3, help="runs per seed and tree")
    ap.add_argument("--parts", nargs="+", default=["link", "cpu", "sim"],
                    choices=["link", "cpu", "sim"], help="what to measure")
    args = ap.parse_args()
    if args.quick:
        args.link_s, args.cmds, args.cpu_pairs, args.cpu_s = 15.0, 50, 1, 15.0
        args.seeds = args.seeds[:1]
        args.sim_reps = 1
    out: dict[str, Any] = {"bench": "shore"}
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        if "link" in args.parts:
            link_figures(args, tmp, out)
        if "cpu" in args.parts:
            cpu_figures(args, tmp, out)
        if "sim" in args.parts:
            sim_figures(args, tmp, out)
    log("; ".join(f"{k} {v}" for k, v in summary(out).items()))
    print(json.dumps(out))


def summary(out: dict[str, Any]) -> dict[str, Any]:
    s: dict[str, Any] = {}
    if "telemetry_latency_ms" in out:
        s["latency p50/p99 ms"] = (f"{out['telemetry_latency_ms']['p50']}/"
                                   f"{out['telemetry_latency_ms']['p99']}")
        s["rtt p50/p99 ms"] = f"{out['command_rtt_ms']['p50']}/{out['command_rtt_ms']['p99']}"
        s["viewer/unauthenticated accepted"] = (
            f"{out['security']['viewer_commands_accepted']}/"
            f"{out['security']['unauthenticated_connected']}")
    if "cpu" in out:
        s["link cpu %"] = out["cpu"]["link_pct_of_a_core"]
    if "sim_speed" in out:
        s["sim speed ratio"] = out["sim_speed"]["ratio"]
    return s


def link_figures(args: argparse.Namespace, tmp: Path, out: dict[str, Any]) -> None:
    runs = []
    for auth in ("none", "usrpwd", "mtls"):
        log(f"link run, auth {auth}: {args.link_s:g} s of telemetry, {args.cmds} commands")
        r = link_run(auth, tmp, args.link_s, args.cmds)
        lat, rtt = r["latency_samples"], r["rtt"]
        log(f"  state latency p50 {ms(pct(lat, 50))} ms p99 {ms(pct(lat, 99))} ms "
            f"({len(lat)}); command rtt p50 {ms(pct(rtt, 50))} ms p99 {ms(pct(rtt, 99))} ms;"
            f" link loss → {r['link_loss_mode']} after {r['link_loss_action_s']:.3f} s"
            + (f"; security {r['security']}" if "security" in r else ""))
        runs.append(r)
    lat_all = [x for r in runs for x in r["latency_samples"]]
    rtt_all = [x for r in runs for x in r["rtt"]]
    out["telemetry_latency_ms"] = {"p50": ms(pct(lat_all, 50)), "p99": ms(pct(lat_all, 99)),
                                   "max": ms(max(lat_all)), "samples": len(lat_all)}
    out["telemetry_latency_ms_by_auth"] = {
        r["auth"]: {"p50": ms(pct(r["latency_samples"], 50)),
                    "p99": ms(pct(r["latency_samples"], 99))} for r in runs}
    gaps = [x for r in runs for x in r["state_intervals"]]
    # the boat's state publications (its own stamps), nominally 200 ms apart (5 Hz)
    out["state_interval_ms"] = {"p50": ms(pct(gaps, 50)), "p99": ms(pct(gaps, 99)),
                                "max": ms(max(gaps)), "samples": len(gaps)}
    out["command_rtt_ms"] = {"p50": ms(pct(rtt_all, 50)), "p99": ms(pct(rtt_all, 99)),
                             "max": ms(max(rtt_all)), "samples": len(rtt_all)}
    out["command_rtt_ms_by_auth"] = {
        r["auth"]: {"p50": ms(pct(r["rtt"], 50)), "p99": ms(pct(r["rtt"], 99))}
        for r in runs}
    acts = [r["link_loss_action_s"] for r in runs]
    out["link_loss"] = {"link_lost_s": LINK_LOST_S,
                        "action_s": [round(a, 3) for a in acts],
                        "excess_max_s": round(max(acts) - LINK_LOST_S, 3),
                        "modes": [r["link_loss_mode"] for r in runs]}
    sec = [r["security"] for r in runs if "security" in r]
    out["security"] = {
        "viewer_commands_sent": sum(s["viewer_commands"] for s in sec),
        "viewer_commands_accepted": sum(s["viewer_replies"] + s["acks_during_viewer_phase"]
                                        for s in sec),
        "unauthenticated_attempts": sum(s["unauthenticated_attempts"] for s in sec),
        "unauthenticated_connected": sum(s["unauthenticated_connected"] for s in sec),
        "mode_after_viewer_phase": [s["mode_after"] for s in sec]}


def cpu_figures(args: argparse.Namespace, tmp: Path, out: dict[str, Any]) -> None:
    # CPU with and without the link, alternated
    with_s: list[float] = []
    without_s: list[float] = []
    for k in range(args.cpu_pairs):
        for with_link in (False, True):
            log(f"cpu pair {k + 1}/{args.cpu_pairs}: {args.cpu_s:g} s real time, "
                f"shore link {'on' if with_link else 'off'}")
            c = cpu_run(with_link, args.cpu_s, tmp, k)
            (with_s if with_link else without_s).append(c / args.cpu_s)
            log(f"  {100 * c / args.cpu_s:.2f} % of a core")
    diffs = [100 * (w - o) for w, o in zip(with_s, without_s, strict=True)]
    out["cpu"] = {"runtime_without_link_pct": round(100 * statistics.fmean(without_s), 2),
                  "runtime_with_link_pct": round(100 * statistics.fmean(with_s), 2),
                  "link_pct_of_a_core": round(statistics.fmean(diffs), 2),
                  "link_pct_per_pair": [round(d, 2) for d in diffs],
                  "window_s": args.cpu_s}


def sim_figures(args: argparse.Namespace, tmp: Path, out: dict[str, Any]) -> None:
    # simulation speed, link disabled: this tree against the base commit
    base = args.base or subprocess.run(["git", "merge-base", "HEAD", "main"], cwd=ROOT,
                                       capture_output=True, text=True).stdout.strip()
    btree = tmp / "base"
    btree.mkdir()
    arch = subprocess.run(["git", "archive", base], cwd=ROOT, capture_output=True,
                          check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(btree)], input=arch, check=True)
    new: list[dict[str, Any]] = []
    old: list[dict[str, Any]] = []
    for seed in args.seeds:
        for label, tree, acc in (("base", btree, old), ("this", ROOT, new)):
            # the fastest of --sim-reps runs: what other load on the machine did not slow
            reps = [sim_speed(tree, seed) for _ in range(args.sim_reps)]
            r = max(reps, key=lambda x: float(x["speedup_cpu"]))
            acc.append(r)
            log(f"sim speed seed {seed} {label}: {r['speedup']}× real time, "
                f"{r['speedup_cpu']}× per CPU second (best of {args.sim_reps}; xtrack "
                f"RMS {r['xtrack_rms_m']:.4f} m)")
    same = all(a["xtrack_rms_m"] == b["xtrack_rms_m"] for a, b in zip(old, new, strict=True))

    def med(rs: list[dict[str, Any]], k: str) -> float:
        return float(statistics.median(r[k] for r in rs))

    out["sim_speed"] = {
        "base_commit": base[:12],
        "base_speedup": med(old, "speedup"), "this_speedup": med(new, "speedup"),
        "ratio": round(med(new, "speedup_cpu") / med(old, "speedup_cpu"), 3),
        "ratio_wall": round(med(new, "speedup") / med(old, "speedup"), 3),
        "ratio_per_seed": [round(b["speedup_cpu"] / a["speedup_cpu"], 3)
                           for a, b in zip(old, new, strict=True)],
        "base_runs_cpu": [r["speedup_cpu"] for r in old],
        "this_runs_cpu": [r["speedup_cpu"] for r in new],
        "same_results": same}


if __name__ == "__main__":
    main()
