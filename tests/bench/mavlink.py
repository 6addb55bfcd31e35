"""Benchmark: the MAVLink endpoint of a simulated boat (``zarco sim --realtime``)
seen from a pymavlink ground station on loopback.

    python tests/bench/mavlink.py [--runs 3] [--window 20] [--commands 300] [--uploads 3]

Each run starts a boat (a new process, another seed) and measures, at the GCS:

* ``heartbeat_hz`` and every stream's rate: at the defaults, then as a GCS asks
  (REQUEST_DATA_STREAM all at 10 Hz, then SET_MESSAGE_INTERVAL ATTITUDE 50 Hz);
* COMMAND_LONG → COMMAND_ACK latency: ``arm`` (through the supervisor) and
  REQUEST_MESSAGE (answered by the endpoint), p50 / p99;
* the time to upload a 100-waypoint mission (MISSION_COUNT → MISSION_ACK accepted);
* the boat process's CPU over the window with the endpoint streaming, and the
  same boat without the endpoint: the difference is the endpoint's;

and one run with a signing key counts what an unsigned, a wrongly signed and a
replaying GCS got accepted (commands, mode, arming, parameters, missions,
joystick): it must be 0.

Progress on stderr; one JSON line of figures on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]
os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "common")

from test_mavlink_gcs import (  # noqa: E402
    BOAT,
    Gcs,
    free_udp_port,
    geo,
    mav,
    start_boat,
    stop_boat,
)

from zarco_runtime.links.mavlink.settings import STREAMS  # noqa: E402

CLK = os.sysconf("SC_CLK_TCK")


def say(*a: Any) -> None:
    print(*a, file=sys.stderr, flush=True)


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (all its threads)."""
    f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / CLK


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, round(q / 100.0 * (len(s) - 1)))]


def rates(gcs: Gcs, seconds: float) -> dict[str, float]:
    """Messages per second of each type received over ``seconds``."""
    n0 = len(gcs.log)
    t0 = time.monotonic()
    gcs.run_for(seconds)
    dt = time.monotonic() - t0
    counts: dict[str, int] = {}
    for _, m in gcs.log[n0:]:
        counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
    return {k: round(counts.get(k, 0) / dt, 2) for k in STREAMS if k != "HOME_POSITION"}


def latency_ms(gcs: Gcs, n: int, cmd: int, *params: float) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        r = gcs.command(cmd, *params)
        out.append((time.perf_counter() - t0) * 1000.0)
        assert r == mav.MAV_RESULT_ACCEPTED, (r, gcs.texts[-3:])
    return out


def mission_100() -> list[tuple[int, int, float, float, float]]:
    """A 100-waypoint lawnmower, 5 m apart, 20 m lines."""
    g6 = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    items: list[tuple[int, int, float, float, float]] = [
        (mav.MAV_FRAME_MISSION, mav.MAV_CMD_DO_CHANGE_SPEED, 1.0, 0.0, 0.0)]
    for i in range(100):
        n = 5.0 * (i // 2)
        e = 20.0 * (((i + 1) // 2) % 2)
        lat, lon = geo(n, e)
        items.append((g6, mav.MAV_CMD_NAV_WAYPOINT, 0.0, lat, lon))
    return items


def one_run(run: int, args: argparse.Namespace) -> dict[str, Any]:
    out: dict[str, Any] = {}
    gcs = Gcs("udpin:127.0.0.1:0")
    # (the supervisor's per-source rate limit would refuse the latency runs'
    # back-to-back commands "rate limited": lifted, it is not what is measured)
    boat = start_boat(f"udpout:127.0.0.1:{gcs.port}", f"scenario.seed={run + 1}",
                      "runtime.supervisor.command_rate_hz=10000",
                      "runtime.supervisor.command_burst=100000", max_s=3600.0)
    try:
        gcs.heartbeat(lambda m: True, timeout=30.0)
        gcs.wait("GPS_RAW_INT", lambda m: m.fix_type >= mav.GPS_FIX_TYPE_3D_FIX, 20.0)
        gcs.run_for(2.0)
        say(f"run {run + 1}: rates at the defaults ({args.window:g} s)")
        c0, t0 = cpu_s(boat.pid), time.monotonic()
        out["default"] = rates(gcs, args.window)
        out["cpu_with"] = 100.0 * (cpu_s(boat.pid) - c0) / (time.monotonic() - t0)
        say(f"run {run + 1}: REQUEST_DATA_STREAM all at 10 Hz, ATTITUDE at 50 Hz")
        gcs.mav.request_data_stream_send(BOAT[0], BOAT[1], mav.MAV_DATA_STREAM_ALL, 10, 1)
        assert gcs.command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, mav.MAVLINK_MSG_ID_ATTITUDE,
                           20000) == mav.MAV_RESULT_ACCEPTED
        gcs.run_for(1.0)
        c0, t0 = cpu_s(boat.pid), time.monotonic()
        out["requested"] = rates(gcs, args.window / 2)
        out["cpu_with_fast"] = 100.0 * (cpu_s(boat.pid) - c0) / (time.monotonic() - t0)
        gcs.mav.request_data_stream_send(BOAT[0], BOAT[1], mav.MAV_DATA_STREAM_ALL, 0, 0)
        for name in STREAMS:  # back to the defaults
            if name not in ("HEARTBEAT", "HOME_POSITION"):
                gcs.command(mav.MAV_CMD_SET_MESSAGE_INTERVAL,
                            getattr(mav, f"MAVLINK_MSG_ID_{name}"), 0)
        say(f"run {run + 1}: {args.commands} × arm and REQUEST_MESSAGE")
        out["lat_arm"] = latency_ms(gcs, args.commands, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        out["lat_req"] = latency_ms(gcs, args.commands, mav.MAV_CMD_REQUEST_MESSAGE,
                                    mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mav.MAV_RESULT_ACCEPTED
        say(f"run {run + 1}: {args.uploads} × upload of 100 waypoints")
        items = mission_100()
        ups = []
        for _ in range(args.uploads):
            t0 = time.perf_counter()
            r = gcs.upload(items)
            ups.append(time.perf_counter() - t0)
            assert r == mav.MAV_MISSION_ACCEPTED, (r, gcs.texts[-3:])
        out["upload_s"] = ups
    finally:
        err = stop_boat(boat)
        gcs.close()
    if boat.returncode != 0:
        say(err[-2000:])
        raise SystemExit(f"the boat ended with {boat.returncode}")
    # the same boat without the endpoint, same window
    say(f"run {run + 1}: the boat without the endpoint ({args.window:g} s)")
    p = start_boat("udpout:127.0.0.1:9", f"scenario.seed={run + 1}",
                   "runtime.mavlink.enabled=false", max_s=3600.0)
    try:
        time.sleep(6.0)
        c0, t0 = cpu_s(p.pid), time.monotonic()
        time.sleep(args.window)
        out["cpu_without"] = 100.0 * (cpu_s(p.pid) - c0) / (time.monotonic() - t0)
    finally:
        stop_boat(p)
    return out


def signing_run(key_dir: Path) -> dict[str, int]:
    """What GCSs without the key got accepted from a boat with signing on."""
    key = os.urandom(32)
    kf = key_dir / "bench-mav.key"
    kf.write_bytes(key)
    port = free_udp_port()
    boat = start_boat(f"udpin:127.0.0.1:{port}", f'runtime.mavlink.signing_key_file="{kf}"',
                      max_s=600.0)
    url = f"udpout:127.0.0.1:{port}"
    good = Gcs(url, 255, 190, key=key)
    plain = Gcs(url, 254, 190)
    wrong = Gcs(url, 253, 190, key=os.urandom(32), accept_any=True)
    sent = accepted = 0
    try:
        good.heartbeat(lambda m: True, timeout=30.0)
        good.wait("GPS_RAW_INT", lambda m: m.fix_type >= mav.GPS_FIX_TYPE_3D_FIX, 20.0)
        for g in (plain, wrong):
            g.heartbeat(lambda m: True, timeout=5.0)
        kp0 = good.params()["CTL_SPD_KP"]
        # the signed GCS arms and takes manual: anything the others got accepted
        # would show as a mode change, a disarm or thrust
        assert good.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
        assert good.command(mav.MAV_CMD_DO_SET_MODE, 1, 0) == mav.MAV_RESULT_ACCEPTED
        commands = [
            (mav.MAV_CMD_COMPONENT_ARM_DISARM, (0,)),
            (mav.MAV_CMD_COMPONENT_ARM_DISARM, (1,)),
            (mav.MAV_CMD_DO_SET_MODE, (1, 5)),
            (mav.MAV_CMD_DO_SET_MODE, (1, 4)),
            (mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, ()),
            (mav.MAV_CMD_NAV_LOITER_UNLIM, ()),
            (mav.MAV_CMD_MISSION_START, ()),
            (mav.MAV_CMD_REQUEST_MESSAGE, (mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION,)),
        ]
        items = mission_100()[:5]
        for rnd in range(10):
            n0 = len(good.log)
            for g in (plain, wrong):
                for cmd, params in commands:
                    sent += 1
                    accepted += g.command(cmd, *params) == mav.MAV_RESULT_ACCEPTED
                sent += 1
                accepted += g.param_set("CTL_SPD_KP", 10.0 + rnd) != kp0
                sent += 1
                g.mav.mission_count_send(BOAT[0], BOAT[1], len(items),
                                         mav.MAV_MISSION_TYPE_MISSION)
                ack = g.wait("MISSION_ACK", lambda m, s=g.sysid: m.target_system == s)
                accepted += ack.type == mav.MAV_MISSION_ACCEPTED
                sent += 1
                g.mav.set_mode_send(BOAT[0], mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5)
                ack = g.wait("COMMAND_ACK", lambda m, s=g.sysid: m.target_system == s
                             and m.command == mav.MAVLINK_MSG_ID_SET_MODE)
                accepted += ack.result == mav.MAV_RESULT_ACCEPTED
                for _ in range(10):  # the joystick, full ahead
                    g.mav.manual_control_send(BOAT[0], 1000, 0, 0, 0, 0)
                    g.pump(0.05)
                    sent += 1
            # a signed command replayed byte for byte
            msg = good.mav.command_long_encode(BOAT[0], BOAT[1],
                                               mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0,
                                               0, 0, 0, 0)
            buf = msg.pack(good.mav)
            good.mav.seq = (good.mav.seq + 1) % 256
            good.conn.write(buf)
            ack = good.wait("COMMAND_ACK", lambda a: a.target_system == 255)
            assert ack.result == mav.MAV_RESULT_ACCEPTED  # the original
            sent += 1
            good.conn.write(buf)
            ack = good.wait("COMMAND_ACK", lambda a: a.target_system == 255)
            accepted += ack.result == mav.MAV_RESULT_ACCEPTED
            good.run_for(1.2)
            seen = [m for _, m in good.log[n0:]]
            accepted += sum(1 for m in seen if m.get_type() == "HEARTBEAT" and (
                m.custom_mode != 0 or not m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED))
            accepted += sum(1 for m in seen if m.get_type() == "SERVO_OUTPUT_RAW"
                            and (m.servo1_raw, m.servo2_raw) != (1500, 1500))
            say(f"signing: round {rnd + 1}/10, {sent} sent, {accepted} accepted")
        accepted += good.params()["CTL_SPD_KP"] != kp0
    finally:
        stop_boat(boat)
        for g in (good, plain, wrong):
            g.close()
        kf.unlink()
    return {"unsigned_sent": sent, "unsigned_accepted": accepted}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--window", type=float, default=20.0, help="rate/CPU window (s)")
    ap.add_argument("--commands", type=int, default=300, help="commands per latency figure")
    ap.add_argument("--uploads", type=int, default=3, help="100-waypoint uploads per run")
    args = ap.parse_args()
    runs = [one_run(i, args) for i in range(args.runs)]
    say("signing run")
    sig = signing_run(Path(os.environ.get("TMPDIR", "/tmp")))

    def mean_rates(key: str) -> dict[str, float]:
        return {k: round(statistics.mean(r[key][k] for r in runs), 2) for k in runs[0][key]}

    arm = [x for r in runs for x in r["lat_arm"]]
    req = [x for r in runs for x in r["lat_req"]]
    ups = [x for r in runs for x in r["upload_s"]]
    cpu_with = statistics.mean(r["cpu_with"] for r in runs)
    cpu_without = statistics.mean(r["cpu_without"] for r in runs)
    default_rates = mean_rates("default")
    figures = {
        "runs": args.runs,
        "heartbeat_hz": default_rates["HEARTBEAT"],
        "rates_default_set_hz": {k: v for k, v in STREAMS.items() if k != "HOME_POSITION"},
        "rates_default_hz": default_rates,
        "rates_requested_set_hz": {**{k: 10.0 for k in STREAMS if k not in (
            "HEARTBEAT", "HOME_POSITION")}, "HEARTBEAT": 1.0, "ATTITUDE": 50.0},
        "rates_requested_hz": mean_rates("requested"),
        "ack_latency_arm_ms": {"p50": round(pct(arm, 50), 2), "p99": round(pct(arm, 99), 2),
                               "n": len(arm)},
        "ack_latency_request_message_ms": {"p50": round(pct(req, 50), 2),
                                           "p99": round(pct(req, 99), 2), "n": len(req)},
        "upload_100_wp_s": {"median": round(statistics.median(ups), 3),
                            "max": round(max(ups), 3), "n": len(ups)},
        "cpu_boat_with_endpoint_percent": round(cpu_with, 2),
        "cpu_boat_without_endpoint_percent": round(cpu_without, 2),
        "cpu_endpoint_percent": round(cpu_with - cpu_without, 2),
        "cpu_boat_with_endpoint_fast_streams_percent": round(
            statistics.mean(r["cpu_with_fast"] for r in runs), 2),
        **sig,
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
