"""Operators' zenoh clients as zenoh users write them: the heartbeat through a
declared publisher for 60 s against ``failsafe.link_lost_s = 10`` keeps the
link, RTCM through a declared publisher, zenoh.ext's advanced publisher and
``session.put`` all reach the GPS, a querier gets its reply; a viewer's
heartbeats and corrections, sent the same ways, are not heard.

Two simulated boats in their own processes, one with ``auth = "usrpwd"`` and
one with ``auth = "mtls"``, run side by side (one minute of CI, not two)."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Any

import zenoh
from shore_support import Boat, Pki, boats, connect_when_up, free_port, write_users
from zenoh.ext import CacheConfig, MissDetectionConfig, declare_advanced_publisher

from drivers.rtcm import frame
from zarco_runtime.links.shore.zenoh_config import client_config

#: how long the operator's declared publisher keeps the link (s)
HOLD_S = 60.0
LINK_LOST_S = 10.0


def _open(cfg: dict[str, Any]) -> Any:
    return zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))


class Watch:
    """Every ``state`` and ``health`` of one vessel, as a viewer receives them."""

    def __init__(self, session: Any, vessel: str) -> None:
        self.states: list[dict[str, Any]] = []
        self.health: dict[str, Any] = {}
        self.events: list[dict[str, Any]] = []
        self.lock = threading.Lock()
        for kind in ("state", "health", "event"):
            session.declare_subscriber(f"zarco/{vessel}/{kind}", self._cb(kind))

    def _cb(self, kind: str) -> Any:
        def cb(sample: Any) -> None:
            obj = json.loads(sample.payload.to_bytes())
            with self.lock:
                if kind == "state":
                    self.states.append(obj)
                elif kind == "health":
                    self.health = obj
                else:
                    self.events.append(obj)
        return cb

    def wait(self, what: str, pred: Any, timeout_s: float = 30.0) -> Any:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self.lock:
                v = self.states[-1] if what == "state" and self.states else self.health
            if v and pred(v):
                return v
            time.sleep(0.05)
        raise AssertionError(f"{what} never satisfied the condition; last {v}")


def _exercise(ep: str, vessel: str, operator: dict[str, Any], viewer: dict[str, Any],
              out: dict[str, Any]) -> None:
    """One boat: the operator's publishers for ``HOLD_S`` while a viewer tries the
    same; results (or the failure) in ``out``."""
    try:
        op = connect_when_up(lambda: _open(operator), 60.0)
        view = _open(viewer)
        try:
            watch = Watch(view, vessel)
            watch.wait("state", lambda s: s["mode"] == "lines", 60.0)
            with watch.lock:  # the minute under way starts here (idle before the mission)
                del watch.states[:-1]
            # the operator's heartbeat as zenoh's examples send a periodic value
            hb = op.declare_publisher(f"zarco/{vessel}/operator")
            # corrections through a declared publisher, an advanced publisher and put
            rtcm_pub = op.declare_publisher(f"zarco/{vessel}/rtcm")
            rtcm_adv = declare_advanced_publisher(
                op, f"zarco/{vessel}/rtcm", cache=CacheConfig(max_samples=1),
                sample_miss_detection=MissDetectionConfig(heartbeat=5),
                publisher_detection=True)
            # the viewer tries every way: nothing of it may be heard
            v_hb = view.declare_publisher(f"zarco/{vessel}/operator")
            v_rtcm = view.declare_publisher(f"zarco/{vessel}/rtcm")
            f1005 = frame(bytes((0x3E, 0xD0)) + bytes(17))
            beats = frames = 0
            t0 = time.monotonic()
            k = 0
            while time.monotonic() - t0 < HOLD_S:
                beat = json.dumps({"t": time.time(), "user": "alice"})
                hb.put(beat)
                beats += 1
                v_hb.put(json.dumps({"t": time.time(), "user": "bob"}))
                view.put(f"zarco/{vessel}/operator", json.dumps({"t": time.time(),
                                                                 "user": "bob"}))
                sender = (rtcm_pub.put, rtcm_adv.put,
                          lambda b: op.put(f"zarco/{vessel}/rtcm", b))[k % 3]
                sender(f1005)
                frames += 1
                v_rtcm.put(f1005)
                view.put(f"zarco/{vessel}/rtcm", f1005)
                k += 1
                time.sleep(1.0)
            out["states"] = list(watch.states)
            out["events"] = list(watch.events)
            # every operator heartbeat and frame was heard, and none of the viewer's
            # (heartbeats and corrections are separate subscribers: under load the
            # last frame may be counted a health period after the last heartbeat)
            watch.wait("health", lambda h: (
                h["link"].get("heartbeats", 0) >= beats
                and h.get("devices", {}).get("gps", {}).get("counters", {})
                .get("rtcm_frames", 0) >= frames))
            time.sleep(2.5)  # two more health periods: nothing else arrives
            out["health"] = watch.health
            out["beats"], out["frames"] = beats, frames
            # a querier (zenoh's z_querier) gets its one reply
            querier = op.declare_querier(f"zarco/{vessel}/cmd/thrust", timeout=5.0)
            out["querier"] = [json.loads(r.ok.payload.to_bytes())
                              for r in querier.get(payload='{"u1": 1, "u2": 1}')
                              if r.ok is not None]
        finally:
            op.close()
            view.close()
    except BaseException as exc:  # reported by the test's thread
        out["error"] = exc


def _check(out: dict[str, Any]) -> None:
    if "error" in out:
        raise out["error"]
    states = out["states"]
    # under way the whole minute, never the link-lost failsafe
    assert len(states) >= 5 * HOLD_S * 0.8, len(states)
    assert all(s["mode"] == "lines" for s in states), {s["mode"] for s in states}
    assert not any("link_lost" in s["failsafes"] for s in states)
    assert not [e for e in out["events"] if e["kind"] == "failsafe"], out["events"]
    link = out["health"]["link"]
    assert link["heartbeats"] == out["beats"], (link, out["beats"])
    gps = out["health"]["devices"]["gps"]["counters"]
    assert gps["rtcm_frames"] == out["frames"], (gps, out["frames"])
    assert len(out["querier"]) == 1, out["querier"]
    assert out["querier"][0]["reason"] == "not in manual mode"


def test_declared_publishers_keep_the_link_and_viewers_stay_unheard(tmp_path: Path) -> None:
    users = write_users(tmp_path / "users", {"alice": "op-secret", "bob": "view-secret"})
    pki = Pki(tmp_path / "pki")
    boat_cert, boat_key = pki.issue("boat-bravo")
    alice, bob = pki.issue("alice"), pki.issue("bob")
    ep_pw = f"tcp/127.0.0.1:{free_port()}"
    ep_tls = f"tls/127.0.0.1:{free_port()}"
    common = [f"runtime.failsafe.link_lost_s={LINK_LOST_S}", 'runtime.shore.operators=["alice"]',
              'runtime.shore.viewers=["bob"]']
    b_pw = Boat([f'runtime.shore.listen=["{ep_pw}"]', "runtime.shore.vessel=alpha",
                 'runtime.shore.auth="usrpwd"', f'runtime.shore.users_file="{users}"', *common],
                log=tmp_path / "alpha.log")
    b_tls = Boat([f'runtime.shore.listen=["{ep_tls}"]', "runtime.shore.vessel=bravo",
                  'runtime.shore.auth="mtls"', f'runtime.shore.cert_file="{boat_cert}"',
                  f'runtime.shore.key_file="{boat_key}"',
                  f'runtime.shore.ca_file="{pki.ca_file}"', *common],
                 log=tmp_path / "bravo.log")
    runs = {
        "alpha": (ep_pw, client_config(ep_pw, user="alice", password="op-secret"),
                  client_config(ep_pw, user="bob", password="view-secret")),
        "bravo": (ep_tls, client_config(ep_tls, cert_file=alice[0], key_file=alice[1],
                                        ca_file=pki.ca_file),
                  client_config(ep_tls, cert_file=bob[0], key_file=bob[1],
                                ca_file=pki.ca_file)),
    }
    outs: dict[str, dict[str, Any]] = {v: {} for v in runs}
    with boats(b_pw, b_tls):
        threads = [threading.Thread(target=_exercise, args=(ep, v, op, view, outs[v]),
                                    name=f"exercise-{v}")
                   for v, (ep, op, view) in runs.items()]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    for v in runs:
        _check(outs[v])
    assert b_pw.stop() == 0 and b_tls.stop() == 0
