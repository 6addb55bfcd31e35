"""``zarco shore follow --plan FILE`` against a simulated boat over zenoh: the AUV's
plan from a mission file reaches the boat, a bad one is refused with the point
and the reason, ``--no-plan`` follows without one."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from shore_support import ROOT, Boat, boats, free_port, observer, shore

from zarco_core.geodesy import LocalFrame

FOLLOW = ROOT / "config" / "scenarios" / "follow_turn.toml"


def _wait(c: Any, vessel: str, pred: Any, timeout_s: float = 20.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        v = c.snapshot().get(vessel)
        if v is not None and v.state and pred(v.state):
            return dict(v.state)
        time.sleep(0.05)
    raise AssertionError(f"{vessel}: {c.snapshot()[vessel].state}")


def _events(c: Any, vessel: str) -> list[str]:
    return [e["text"] for e in c.snapshot()[vessel].events]


def test_follow_with_a_plan_from_a_file_without_one_and_a_bad_one(tmp_path: Path) -> None:
    frame = LocalFrame(41.185, -8.705)

    def lonlat(n: float, e: float) -> list[float]:
        lat, lon, _ = frame.to_geodetic(n, e)
        return [lon, lat]

    good = tmp_path / "auv.geojson"
    good.write_text(json.dumps({"type": "LineString", "coordinates": [
        lonlat(100.0, 100.0), lonlat(300.0, 100.0), lonlat(300.0, 300.0)]}))
    bad = tmp_path / "bad.geojson"  # its second point 30 cm from the first
    bad.write_text(json.dumps({"type": "LineString", "coordinates": [
        lonlat(100.0, 100.0), lonlat(100.3, 100.0), lonlat(300.0, 300.0)]}))
    ep = f"tcp/127.0.0.1:{free_port()}"
    boat = Boat([f'runtime.shore.listen=["{ep}"]', "mission.kind=idle",
                 "runtime.devices.buoy.enabled=true", "scenario.max_duration_s=120"],
                scenario=FOLLOW, log=tmp_path / "boat.log")
    env = {"ZARCO_SHORE_CONNECT": ep, "ZARCO_SHORE_USER": "alice"}
    with boats(boat):
        obs = observer([ep], ["zarco"])
        try:
            _wait(obs, "zarco", lambda s: s["fix"] != "none")
            deadline = time.monotonic() + 30.0
            while shore("arm", env=env).returncode != 0:
                assert time.monotonic() < deadline, "the boat never armed"
                time.sleep(1.0)
            r = shore("follow", "--plan", str(bad), env=env)
            assert r.returncode == 1, r.stdout + r.stderr
            assert "follow REFUSED: auv_plan[1]: less than 1 m from point 0" in r.stdout
            r = shore("follow", "--plan", str(good), env=env)
            assert r.returncode == 0 and "follow accepted; mode follow" in r.stdout, r.stdout
            _wait(obs, "zarco", lambda s: s["mode"] == "follow")
            deadline = time.monotonic() + 10.0
            while not any(t.startswith("AUV plan of 2 legs (400 m) from shore:alice")
                          for t in _events(obs, "zarco")):
                assert time.monotonic() < deadline, _events(obs, "zarco")
                time.sleep(0.1)
            assert any("with an AUV plan of 3 points" in t for t in _events(obs, "zarco"))
            r = shore("follow", "--no-plan", env=env)
            assert r.returncode == 0, r.stdout + r.stderr
            deadline = time.monotonic() + 10.0
            while "AUV plan cleared; tracking without it" not in _events(obs, "zarco"):
                assert time.monotonic() < deadline, _events(obs, "zarco")
                time.sleep(0.1)
            missing = shore("follow", "--plan", str(tmp_path / "nope.toml"), env=env)
            assert missing.returncode == 2 and "zarco shore: follow:" in missing.stderr
        finally:
            obs.close()
    assert boat.stop() == 0
