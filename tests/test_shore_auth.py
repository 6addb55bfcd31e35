"""The shore link's security with real zenoh sessions on loopback: a simulated boat
(``zarco sim --realtime``, its own process) with ``auth = "usrpwd"`` or ``"mtls"``;
clients with no, wrong or valid credentials, as operator or viewer."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
import zenoh
from shore_support import (
    Boat,
    Pki,
    acks,
    boats,
    connect_when_up,
    free_port,
    wait_ack,
    write_users,
)

from zarco_runtime.links.shore.zenoh_config import client_config
from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient


def _open(cfg: dict[str, Any]) -> Any:
    return zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))


def _client(cred: Credentials, user: str, vessel: str = "") -> ShoreClient:
    c = ShoreClient(ConsoleConfig([cred], user=user, vessel=vessel))
    failed = c.connect()
    if failed:
        c.close()
        raise ConnectionError(failed[0])
    return c


def _wait_state(c: ShoreClient, vessel: str, pred: Any, timeout_s: float = 20.0,
                kind: str = "state") -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    last: dict[str, Any] = {}
    while time.monotonic() < deadline:
        v = c.snapshot().get(vessel)
        last = getattr(v, kind) if v is not None else {}
        if last and pred(last):
            return last
        time.sleep(0.05)
    raise AssertionError(f"{kind} never satisfied the condition; last: {last}")


def _roles_hold(ep: str, op: Credentials, viewer: Credentials, vessel: str) -> None:
    """A viewer watches but its commands have no effect; an operator's are
    acknowledged and acted on."""
    opc = connect_when_up(lambda: _client(op, "alice", vessel))
    view = _client(viewer, "bob", vessel)
    try:
        # both receive telemetry; the rectangle mission starts on its own
        _wait_state(opc, vessel, lambda s: s["mode"] == "lines")
        _wait_state(view, vessel, lambda s: s["mode"] == "lines" and s["lat_deg"] is not None)
        _wait_state(view, vessel, lambda h: h["devices"]["gps"]["state"] == "ok",
                    kind="health")
        # the viewer's commands: no reply, no acknowledgement on the boat, no effect
        for name, args in (("stop", {}), ("mode", {"mode": "hold"}), ("thrust",
                                                                      {"u1": 50, "u2": 50})):
            assert view.command(vessel, name, args, timeout_s=1.0) == []
        # nor through raw zenoh, without the console's attachment
        raw = view.sessions[0][1]
        assert list(raw.get(f"zarco/{vessel}/cmd/stop", payload="{}", timeout=1.0)) == []
        # its heartbeat and corrections are not taken either (nothing to see but no ack)
        view.heartbeat([vessel])
        time.sleep(1.0)
        assert _wait_state(opc, vessel, lambda s: True)["mode"] == "lines"
        assert not any("bob" in a or "shore" in a for a in acks(opc, vessel))
        # the operator's command: acknowledged, and the vessel holds
        replies = opc.command(vessel, "mode", {"mode": "hold"})
        assert len(replies) == 1, replies
        r = replies[0]
        assert r.ok and r.mode == "hold" and r.reason == "" and r.id
        _wait_state(view, vessel, lambda s: s["mode"] == "hold")
        # the acknowledgement event follows the state that shows its effect
        wait_ack(view, vessel, "mode from shore:alice: accepted")
        # a refusal comes back with its reason
        refused = opc.command(vessel, "thrust", {"u1": 10, "u2": 10})
        assert len(refused) == 1 and not refused[0].ok
        assert refused[0].reason == "not in manual mode"
        # a raw zenoh get (no attachment, as any outside tool) is answered too
        sess = opc.sessions[0][1]
        got = list(sess.get(f"zarco/{vessel}/cmd/stop", payload="{}", timeout=3.0))
        assert len(got) == 1 and got[0].ok is not None
        body = json.loads(got[0].ok.payload.to_bytes())
        assert set(body) == {"ok", "id", "mode", "reason"}
        assert body["ok"] is True and body["mode"] == "idle"
        _wait_state(view, vessel, lambda s: s["mode"] == "idle")
    finally:
        opc.close()
        view.close()


def _cannot_connect(cfgs: list[dict[str, Any]]) -> None:
    for cfg in cfgs:
        with pytest.raises(zenoh.ZError):
            s = _open(cfg)
            s.close()  # pragma: no cover (only if it wrongly connected)


def test_usrpwd_roles(tmp_path: Path) -> None:
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    users = write_users(tmp_path / "users", {"alice": "op-secret", "bob": "view-secret",
                                              "carol": "no-role"})
    boat = Boat([f'runtime.shore.listen=["{ep}"]', "runtime.shore.vessel=alpha",
                 'runtime.shore.auth="usrpwd"', f'runtime.shore.users_file="{users}"',
                 'runtime.shore.operators=["alice"]', 'runtime.shore.viewers=["bob"]'],
                log=tmp_path / "boat.log")
    with boats(boat):
        op = Credentials(ep, "alice", "op-secret")
        connect_when_up(lambda: _open(op.zenoh())).close()
        _cannot_connect([
            client_config(ep),                                          # no credentials
            client_config(ep, user="alice", password="wrong"),          # wrong password
            client_config(ep, user="mallory", password="op-secret"),    # unknown user
        ])
        # a user with a password but no role connects, and gets nothing at all
        with _open(client_config(ep, user="carol", password="no-role")) as s:
            got: list[Any] = []
            s.declare_subscriber("zarco/**", got.append)
            assert list(s.get("zarco/alpha/cmd/stop", payload="{}", timeout=1.0)) == []
            time.sleep(0.6)
            assert got == []
        _roles_hold(ep, op, Credentials(ep, "bob", "view-secret"), "alpha")
    assert boat.stop() == 0


def test_mtls_roles(tmp_path: Path) -> None:
    port = free_port()
    ep = f"tls/127.0.0.1:{port}"
    pki = Pki(tmp_path / "pki")
    boat_cert, boat_key = pki.issue("boat-alpha")
    alice = pki.issue("alice")
    bob = pki.issue("bob")
    rogue = Pki(tmp_path / "rogue", "rogue-ca")
    fake_alice = rogue.issue("alice")  # the right name, signed by another CA
    boat = Boat([f'runtime.shore.listen=["{ep}"]', "runtime.shore.vessel=alpha",
                 'runtime.shore.auth="mtls"', f'runtime.shore.cert_file="{boat_cert}"',
                 f'runtime.shore.key_file="{boat_key}"', f'runtime.shore.ca_file="{pki.ca_file}"',
                 'runtime.shore.operators=["alice"]', 'runtime.shore.viewers=["bob"]'],
                log=tmp_path / "boat.log")
    with boats(boat):
        op = Credentials(ep, cert_file=alice[0], key_file=alice[1], ca_file=pki.ca_file)
        connect_when_up(lambda: _open(op.zenoh())).close()
        _cannot_connect([
            client_config(ep, ca_file=pki.ca_file),                     # no certificate
            client_config(ep, cert_file=fake_alice[0], key_file=fake_alice[1],
                          ca_file=pki.ca_file),                         # another CA's
            client_config(f"tcp/127.0.0.1:{port}"),                     # plain TCP
        ])
        _roles_hold(ep, op, Credentials(ep, cert_file=bob[0], key_file=bob[1],
                                        ca_file=pki.ca_file), "alpha")
    assert boat.stop() == 0
