"""``zarco shore`` against simulated boats (``zarco sim --realtime``, own processes):
two vessels on one console, a command to one never reaching the other, the
console's exit status and printed replies, a mission file, the link-loss
failsafe, and the refusal of ``auth = "none"`` off loopback."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from shore_support import (
    RECT,
    ROOT,
    Boat,
    acks,
    boats,
    free_port,
    observer,
    shore,
    wait_ack,
    write_credentials,
    write_users,
)

from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient


def _wait(c: ShoreClient, vessel: str, pred: Any, timeout_s: float = 20.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        v = c.snapshot().get(vessel)
        if v is not None and v.state and pred(v.state):
            return v.state
        time.sleep(0.05)
    raise AssertionError(f"{vessel}: {c.snapshot()[vessel].state}")


def test_two_vessels_one_console(tmp_path: Path) -> None:
    ea, eb = f"tcp/127.0.0.1:{free_port()}", f"tcp/127.0.0.1:{free_port()}"
    a = Boat([f'runtime.shore.listen=["{ea}"]', "runtime.shore.vessel=alpha"],
             log=tmp_path / "alpha.log")
    b = Boat([f'runtime.shore.listen=["{eb}"]', "runtime.shore.vessel=beta",
              "scenario.seed=2"], log=tmp_path / "beta.log")
    env = {"ZARCO_SHORE_CONNECT": f"{ea},{eb}", "ZARCO_SHORE_USER": "alice"}
    with boats(a, b):
        obs = observer([ea, eb], ["alpha", "beta"])
        try:
            for v in ("alpha", "beta"):
                _wait(obs, v, lambda s: s["mode"] == "lines")
            # the status view shows both
            out = shore("status", "--once", "--count", "2", "--json", env=env)
            assert out.returncode == 0, out.stderr
            st = json.loads(out.stdout)
            assert set(st) == {"alpha", "beta"}
            assert all(st[v]["state"]["mode"] == "lines" for v in st)
            assert all(st[v]["health"]["devices"]["gps"]["state"] == "ok" for v in st)
            table = shore("status", "--once", "--count", "2", env=env)
            assert table.returncode == 0 and "alpha" in table.stdout and "beta" in table.stdout
            # a command needs a vessel when two are heard
            amb = shore("stop", env=env)
            assert amb.returncode == 2 and "several vessels" in amb.stderr
            # a command to alpha: acknowledged and acted on by alpha only
            r = shore("--vessel", "alpha", "mode", "hold", env=env)
            assert r.returncode == 0, r.stdout + r.stderr
            assert "alpha: mode accepted; mode hold" in r.stdout
            _wait(obs, "alpha", lambda s: s["mode"] == "hold")
            time.sleep(1.0)
            assert obs.snapshot()["beta"].state["mode"] == "lines"
            wait_ack(obs, "alpha", "mode from shore:alice: accepted")
            assert acks(obs, "beta") == []
            # a refusal: its reason printed, non-zero exit
            r = shore("--vessel", "beta", "thrust", "10", "10", "--duration", "0.5", env=env)
            assert r.returncode == 1
            assert "beta: thrust REFUSED: not in manual mode (mode lines" in r.stdout
            # a mission from a GeoJSON file to beta
            gj = tmp_path / "survey.geojson"
            gj.write_text(json.dumps({"type": "Feature", "properties": {"name": "survey"},
                                      "geometry": {"type": "LineString", "coordinates": [
                                          [-8.7050, 41.1852], [-8.7050, 41.1856],
                                          [-8.7045, 41.1856]]}}))
            r = shore("--vessel", "beta", "mission", str(gj), "--speed", "0.8", env=env)
            assert r.returncode == 0, r.stdout + r.stderr
            _wait(obs, "beta", lambda s: s["legs"] == 2 and s["leg"] == 0)
            assert obs.snapshot()["alpha"].state["mode"] == "hold"
            # the last mission can be resumed after a stop
            assert shore("--vessel", "beta", "stop", env=env).returncode == 0
            _wait(obs, "beta", lambda s: s["mode"] == "idle" and not s["armed"])
            table = shore("status", "--once", "--count", "2", env=env)
            assert [ln.split()[2] for ln in table.stdout.splitlines()
                    if ln.startswith("beta ")] == ["disarmed"], table.stdout
            # armed again from the console, then the mission goes on
            r = shore("--vessel", "beta", "arm", env=env)
            assert r.returncode == 0 and "beta: arm accepted" in r.stdout, r.stdout + r.stderr
            _wait(obs, "beta", lambda s: s["armed"])
            r = shore("--vessel", "beta", "resume", env=env)
            assert r.returncode == 0 and "mode lines" in r.stdout
            table = shore("status", "--once", "--count", "2", env=env)
            assert [ln.split()[1:3] for ln in table.stdout.splitlines()
                    if ln.startswith("beta ")] == [["lines", "ARMED"]], table.stdout
            # disarmed from the console: idle
            r = shore("--vessel", "alpha", "disarm", env=env)
            assert r.returncode == 0 and "alpha: disarm accepted; mode idle" in r.stdout
            _wait(obs, "alpha", lambda s: s["mode"] == "idle" and not s["armed"])
            # a vessel nobody has: no reply
            r = shore("--vessel", "gamma", "stop", env=env)
            assert r.returncode == 3 and "no reply" in r.stderr
            assert acks(obs, "alpha")[-1].startswith("disarm from shore:alice")
        finally:
            obs.close()
    assert a.stop() == 0 and b.stop() == 0


def test_link_loss_holds_after_link_lost_s(tmp_path: Path) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    boat = Boat([f'runtime.shore.listen=["{ep}"]', "runtime.failsafe.link_lost_s=2.0"],
                log=tmp_path / "boat.log")
    with boats(boat):
        obs = observer([ep], ["zarco"])
        op = ShoreClient(ConsoleConfig([Credentials(ep)], user="alice", heartbeat_hz=2.0))
        try:
            assert op.connect() == []
            _wait(obs, "zarco", lambda s: s["mode"] == "lines")
            op.start_heartbeat(["zarco"])
            time.sleep(4.0)  # twice link_lost_s with the heartbeat: still under way
            assert obs.snapshot()["zarco"].state["mode"] == "lines"
            op.stop_heartbeat()
            t_last = op.last_heartbeat
            assert t_last is not None
            _wait(obs, "zarco", lambda s: s["mode"] == "hold", timeout_s=10.0)
            # the events may follow the state that shows the hold
            deadline = time.monotonic() + 10.0
            while True:
                evs = obs.snapshot()["zarco"].events
                fs = [e for e in evs if e["kind"] == "failsafe" and "link_lost" in e["text"]]
                hold = [e for e in evs if e["kind"] == "mode" and "mode hold" in e["text"]
                        and "link_lost" in e["text"]]
                if (fs and hold) or time.monotonic() > deadline:
                    break
                time.sleep(0.05)
            assert fs and hold, evs
            # the boat's own times: not before link_lost_s without a heartbeat, and
            # within its failsafe evaluation period (20 Hz) after it
            assert 2.0 <= hold[0]["t"] - t_last <= 2.0 + 0.1, hold[0]["t"] - t_last
        finally:
            op.close()
            obs.close()


def test_console_credentials_from_a_file_not_the_command_line(tmp_path: Path) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    users = write_users(tmp_path / "users", {"alice": "s3cret", "bob": "other"})
    boat = Boat([f'runtime.shore.listen=["{ep}"]', 'runtime.shore.auth="usrpwd"',
                 f'runtime.shore.users_file="{users}"', 'runtime.shore.operators=["alice"]',
                 'runtime.shore.viewers=["bob"]'], log=tmp_path / "boat.log")
    cfg = tmp_path / "shore.toml"
    cfg.write_text(f'connect = ["{ep}"]\ncredentials_file = '
                   f'"{write_credentials(tmp_path / "alice.cred", "alice", "s3cret")}"\n')
    with boats(boat):
        deadline = time.monotonic() + 30.0
        while (r := shore("--config", str(cfg), "stop")).returncode != 0:
            assert time.monotonic() < deadline, r.stdout + r.stderr
            time.sleep(0.3)
        assert "zarco: stop accepted; mode idle" in r.stdout
        # the same from the environment; a viewer gets no reply; a wrong password no link
        env = {"ZARCO_SHORE_CONNECT": ep, "ZARCO_SHORE_USER": "bob",
               "ZARCO_SHORE_PASSWORD": "other", "ZARCO_SHORE_VESSEL": "zarco"}
        r = shore("stop", env=env)
        assert r.returncode == 3 and "no reply" in r.stderr
        r = shore("stop", env={**env, "ZARCO_SHORE_PASSWORD": "guess"})
        assert r.returncode == 2 and "cannot connect" in r.stderr
        # there is no option to give a password
        r = shore("stop", "--password=s3cret")
        assert r.returncode == 2 and "unrecognized arguments: --password" in r.stderr


def test_auth_none_off_loopback_is_refused_at_start() -> None:
    out = subprocess.run([sys.executable, "-m", "zarco_runtime.cli", "sim", str(RECT),
                          "--realtime", "-q", "--set", "runtime.shore.enabled=true",
                          "--set", 'runtime.shore.listen=["tcp/0.0.0.0:7447"]'],
                         capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert out.returncode == 2
    assert f"{RECT}: runtime.shore.auth: 'none' is allowed only when every " \
           "listen endpoint is on loopback, and tcp/0.0.0.0:7447 is not" in out.stderr
