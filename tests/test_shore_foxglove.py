"""``zarco shore foxglove`` against a simulated boat (``zarco sim --realtime``, its
own process, ``auth = "usrpwd"``), read by an independent client speaking the
Foxglove WebSocket protocol (``websockets``: advertise, subscribe, message
data; the SDK's server names it ``foxglove.sdk.v1``, the same protocol as
``foxglove.websocket.v1``, so the client offers both names): the
recordings' topics and schemas, each message valid and equal to what the boat
sent over zenoh (an observer's samples), and a layout that names only topics
both a recording and the live view hold."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from shore_support import (
    ROOT,
    Boat,
    boats,
    connect_when_up,
    free_port,
    write_credentials,
    write_users,
)
from web_support import console_config

from zarco_runtime.links.recorder.schema import SHARED_TOPICS
from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient
from zarco_tools.shore.foxglove.layout import LAYOUT_FILE, layout_json, topics_named

wsc = pytest.importorskip("websockets.sync.client")

FOLLOW = ROOT / "config" / "scenarios" / "follow_turn.toml"
#: the protocol's names: the SDK's server takes the first (the same protocol)
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


class FoxgloveClient:
    """A minimal Foxglove WebSocket client: channels advertised, messages received."""

    def __init__(self, url: str) -> None:
        self.ws = wsc.connect(url, subprotocols=SUBPROTOCOLS, open_timeout=20.0,
                              max_size=None).__enter__()
        assert self.ws.subprotocol in SUBPROTOCOLS
        self.channels: dict[int, dict[str, Any]] = {}
        self.subs: dict[int, int] = {}
        self.got: dict[str, list[tuple[int, dict[str, Any]]]] = {}
        self.server_info: dict[str, Any] = {}
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        try:
            for msg in self.ws:
                if isinstance(msg, str):
                    d = json.loads(msg)
                    with self.lock:
                        if d.get("op") == "serverInfo":
                            self.server_info = d
                        elif d.get("op") == "advertise":
                            for ch in d["channels"]:
                                self.channels[int(ch["id"])] = ch
                        elif d.get("op") == "unadvertise":
                            for cid in d["channelIds"]:
                                self.channels.pop(int(cid), None)
                    continue
                assert msg[0] == 0x01, msg[:1]  # message data
                sub, ns = struct.unpack_from("<IQ", msg, 1)
                with self.lock:
                    topic = self.channels[self.subs[sub]]["topic"]
                    self.got.setdefault(topic, []).append((ns, json.loads(msg[13:])))
        except Exception:  # closed
            return

    def topics(self) -> dict[str, dict[str, Any]]:
        with self.lock:
            return {c["topic"]: c for c in self.channels.values()}

    def subscribe(self, topics: list[str]) -> None:
        subs = []
        with self.lock:
            for c in self.channels.values():
                if c["topic"] in topics:
                    sid = len(self.subs) + 1
                    self.subs[sid] = int(c["id"])
                    subs.append({"id": sid, "channelId": int(c["id"])})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def messages(self, topic: str) -> list[tuple[int, dict[str, Any]]]:
        with self.lock:
            return list(self.got.get(topic, []))

    def close(self) -> None:
        self.ws.close()


def _until(pred: Any, timeout_s: float = 30.0, what: str = "") -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got = pred()
        if got:
            return got
        time.sleep(0.1)
    raise AssertionError(f"never {what}")


def test_live_foxglove_view_has_the_recordings_topics(tmp_path: Path) -> None:
    users = write_users(tmp_path / "users", {"alice": "op-secret"})
    ep = f"tcp/127.0.0.1:{free_port()}"
    boat = Boat([f'runtime.shore.listen=["{ep}"]', "runtime.shore.vessel=gamma",
                 'runtime.shore.auth="usrpwd"', f'runtime.shore.users_file="{users}"',
                 'runtime.shore.operators=["alice"]', "auv.start_delay_s=5.0"],
                scenario=FOLLOW, log=tmp_path / "boat.log")
    cred = write_credentials(tmp_path / "alice.cred", "alice", "op-secret")
    cfg = console_config(tmp_path / "console.toml", [(ep, cred)])
    port = free_port()
    with boats(boat):
        def observe() -> ShoreClient:
            c = ShoreClient(ConsoleConfig([Credentials(ep, "alice", "op-secret")],
                                          user="alice"))
            if c.connect() or "gamma" not in c.wait_vessels(10.0, "gamma"):
                c.close()
                raise ConnectionError("gamma not heard")
            return c

        obs = connect_when_up(observe, 40.0)
        log = (tmp_path / "foxglove.log").open("w")
        proc = subprocess.Popen(
            [sys.executable, "-m", "zarco_runtime.cli", "shore", "foxglove", "--port",
             str(port)], stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
            env={**os.environ, "ZARCO_SHORE_CONFIG": str(cfg)})
        client: FoxgloveClient | None = None
        try:
            client = connect_when_up(lambda: FoxgloveClient(f"ws://127.0.0.1:{port}"), 30.0)
            names = [f"{p}{t}" for p in ("", "/gamma") for t in SHARED_TOPICS]
            topics = _until(lambda: (tp := client.topics()) and set(names) <= set(tp) and tp,
                            40.0, "every topic advertised")
            # the recordings' schemas, JSON, named as in a recording
            for name in names:
                ch = topics[name]
                schema_name, schema = SHARED_TOPICS[name.removeprefix("/gamma")]
                assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema"
                assert ch["schemaName"] == schema_name
                assert json.loads(ch["schema"]) == schema
            client.subscribe(list(SHARED_TOPICS))
            # an event: the operator holds, then follows again
            _until(lambda: client.messages("/shore/state"), 20.0, "a state")
            assert obs.command("gamma", "mode", {"mode": "hold"})[0].ok
            _until(lambda: client.messages("/foxglove/auv") and len(
                client.messages("/shore/state")) > 25, 40.0, "an AUV and 5 s of states")
            assert obs.command("gamma", "follow", {})[0].ok
            _until(lambda: any("follow from shore:alice" in m["message"]
                               for _, m in client.messages("/foxglove/events")), 20.0,
                   "the follow event")
            ref = obs.snapshot()["gamma"]
            for topic in SHARED_TOPICS:
                msgs = client.messages(topic)
                assert msgs, topic
                for ns, m in msgs:
                    jsonschema.validate(m, SHARED_TOPICS[topic][1])
                    t = m["t"] if "t" in m else (m["timestamp"]["sec"]
                                                 + m["timestamp"]["nsec"] * 1e-9)
                    assert abs(ns / 1e9 - t) < 1e-6  # logged at the boat's time
            # the states are the boat's, as sent; the map fixes are their positions
            states = {m["t"]: m for _, m in client.messages("/shore/state")}
            assert ref.state["t"] in states or ref.state["t"] > max(states)
            if ref.state["t"] in states:
                assert states[ref.state["t"]] == ref.state
            for _, fix in client.messages("/foxglove/vessel")[::5]:
                t = round(fix["timestamp"]["sec"] + fix["timestamp"]["nsec"] * 1e-9, 3)
                st = states[t]
                assert (fix["latitude"], fix["longitude"]) == (st["lat_deg"], st["lon_deg"])
            auvs = {m["t"]: m for _, m in client.messages("/shore/auv")}
            for _, fix in client.messages("/foxglove/auv"):
                t = round(fix["timestamp"]["sec"] + fix["timestamp"]["nsec"] * 1e-9, 3)
                a = auvs[t]
                assert (fix["latitude"], fix["longitude"]) == (a["lat_deg"], a["lon_deg"])
                nn, ne, ee = a["pos_cov_m2"]
                assert fix["position_covariance"][:5] == [ee, ne, 0.0, ne, nn]
            texts = [m["message"] for _, m in client.messages("/foxglove/events")]
            assert any(t.startswith("mode from shore:alice: accepted") for t in texts), texts
            assert client.messages("/gamma/shore/state") == []  # not subscribed: not sent
        finally:
            if client is not None:
                client.close()
            proc.send_signal(signal.SIGTERM)
            try:
                assert proc.wait(15.0) == 0
            finally:
                if proc.poll() is None:
                    proc.kill()
                log.close()
                obs.close()


def test_the_layout_shows_only_what_live_and_recorded_data_both_hold(tmp_path: Path) -> None:
    assert LAYOUT_FILE.read_text(encoding="utf-8") == layout_json()
    named = topics_named(json.loads(LAYOUT_FILE.read_text(encoding="utf-8")))
    assert named == set(SHARED_TOPICS), named
    out = tmp_path / "layout.json"
    r = subprocess.run([sys.executable, "-m", "zarco_runtime.cli", "shore", "foxglove",
                        "--save-layout", str(out)], capture_output=True, text=True, cwd=ROOT,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert out.read_text(encoding="utf-8") == LAYOUT_FILE.read_text(encoding="utf-8")
