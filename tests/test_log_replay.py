"""``zarco log replay`` of a real ``zarco run``: the vessel process on pseudo-terminals
(the simulated devices' bytes written into them in real time), a mission started,
stopped with SIGTERM; its recording replayed on the virtual clock gives back the
recorded navigation exactly, with the thruster commands the boat sent as the
estimator's input."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from test_record_restart import _arm, _ctl, _start, _wait, pty_rig

from zarco_tools.log.reader import iter_messages, open_recording
from zarco_tools.log.replay import replay, report

ROOT = Path(__file__).resolve().parents[1]


def test_replay_of_a_real_run_reproduces_its_navigation(tmp_path: Path) -> None:
    cfg, feeder = pty_rig(tmp_path, "")
    lat, lon = feeder.origin
    sock = tmp_path / "ctl.sock"
    log = tmp_path / "runtime.log"
    p = _start(cfg, log)
    try:
        assert _wait(lambda: sock.exists() and _ctl(sock, "status").get("mode"), 30), \
            log.read_text()
        assert _wait(lambda: _ctl(sock, "status")["devices"]["gps"]["state"] == "ok", 15)
        # a parameter change before leaving: recorded, and applied again by the replay
        p_ack = _ctl(sock, "param", {"name": "failsafe.link_lost_s", "value": 25})
        assert p_ack["ok"], p_ack
        assert _arm(sock)
        ack = _ctl(sock, "mission", {"waypoints": [[lat, lon], [lat + 0.0005, lon]],
                                     "speed_mps": 1.0, "start": True})
        assert ack["ok"], ack
        time.sleep(3.0)
        p.send_signal(signal.SIGTERM)
        assert p.wait(timeout=20) == 0
    finally:
        feeder.stop.set()
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    (path,) = sorted((tmp_path / "recordings").glob("*.mcap"))
    rec = open_recording(str(path))
    assert rec.metadata["clock"] == "real" and all(rec.finished.values())

    res = replay(rec)
    r = report(res)
    for key in ("nav", "thruster_commands"):
        assert r[key]["exact"], (key, r[key])
        assert r[key]["recorded"] > 50, (key, r[key])
    # the mission drove the thrusters: the estimator's model had commands to take
    assert sum(abs(c.u1) + abs(c.u2) > 0 for c in res.commands) > 20
    assert r["inputs"]["/Command"] >= 2 and r["late"] == r["lost"] == 0  # arm(s), mission
    assert r["params_applied"] == 1 and res.cfg.failsafe.link_lost_s == 25.0
    assert not r["params_refused"]
    # on a real clock a driver stamps what it parses a little after the raw chunk:
    # the replay plays each chunk at the parse stamp, which the estimator saw
    # (how much later depends on the load of the machine, not on the replay)
    assert r["restamped"] > 0 and r["restamp_max_s"] > 0.0
    assert any(m.json()["pos_valid"] for m in iter_messages(rec, {"/NavState"}))

    # the command-line tool says the same
    out = subprocess.run([sys.executable, "-m", "zarco_runtime.cli", "log", "replay", "--json",
                          str(path)], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    cli = json.loads(out.stdout)
    assert cli["nav"]["exact"] and cli["nav"]["recorded"] == r["nav"]["recorded"]
