"""The shore ``map`` key and the ``access`` probe: the map's content from the
configuration, the status and the mission in force (unit), and on a simulated
boat with ``auth = "usrpwd"`` (its own process, real zenoh sessions): the map
is published and answered to operators and viewers alike; only an operator's
``access`` query is answered."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pymap3d
import zenoh
from shore_support import ROOT, Boat, boats, connect_when_up, free_port, write_users

from zarco_core.auv_messages import AuvPlan, BuoyStatus
from zarco_core.config import build
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import MissionProgress, Mode, VesselStatus
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.guidance.mission import Mission, legs_from_points
from zarco_runtime.links.shore.map_info import MapInfo
from zarco_runtime.links.shore.zenoh_config import client_config
from zarco_runtime.settings import RuntimeConfig

FOLLOW = ROOT / "config" / "scenarios" / "follow_turn.toml"


def _status(home: tuple[float, float] | None) -> VesselStatus:
    return VesselStatus(0.0, 0.0, "lines", True, MissionProgress(), [], {}, {}, {},
                        home_lat_deg=home[0] if home else None,
                        home_lon_deg=home[1] if home else None)


def test_map_holds_origin_home_fence_beacons_and_the_mission_lines() -> None:
    origin = (38.52, -28.63)
    beacons = [[10.0, -20.0, 15.0], [-350.0, 420.0, 40.0], [600.0, 90.0, 25.0]]
    cfg = build(RuntimeConfig, {
        "origin": {"lat_deg": origin[0], "lon_deg": origin[1]},
        "devices": {"buoy": {"enabled": True, "url": "sim://buoy"}},
        "tracker": {"network": {"beacons": beacons, "listener_beacon": 2,
                                "turnaround_s": [0.1, 0.1, 0.1]}},
        "geofence": {"radius_m": 750.0,
                     "polygon": [[38.51, -28.64], [38.53, -28.64], [38.53, -28.62]]}},
        "test")
    frame = LocalFrame(*origin)
    info = MapInfo(cfg, frame)
    pts = [(0.0, 0.0), (120.0, 15.0), (120.0, -80.0)]
    lines = Mission("lines", legs_from_points(pts, 1.0), name="box")
    m = info.build(1.0e9, _status((38.5201, -28.6302)), Directive(0.0, 1, Mode.LINES, lines),
                   BuoyStatus(0.0, "buoy", 0.0, 38.5212345678, -28.6354321, 12.0, 0))
    json.dumps(m, allow_nan=False)
    assert m["t"] == 1.0e9
    assert m["origin"] == {"lat_deg": origin[0], "lon_deg": origin[1]}
    assert m["home"] == {"lat_deg": 38.5201, "lon_deg": -28.6302}
    assert m["geofence"]["radius_m"] == 750.0 and len(m["geofence"]["polygon"]) == 3
    assert m["listener"] == 2 and [b["id"] for b in m["beacons"]] == [1, 2, 3]
    for b, want in zip(m["beacons"], beacons, strict=True):
        lat, lon, _ = pymap3d.ned2geodetic(want[0], want[1], 0.0, *origin, 0.0)
        assert abs(b["lat_deg"] - lat) < 1e-7 and abs(b["lon_deg"] - lon) < 1e-7
        assert b["depth_m"] == want[2]
    assert m["buoy"] == {"lat_deg": 38.521235, "lon_deg": -28.635432}
    assert m["mission"]["kind"] == "lines" and m["mission"]["active"] is True
    assert m["mission"]["name"] == "box" and len(m["mission"]["waypoints"]) == 3
    for (lat, lon), (n, e) in zip(m["mission"]["waypoints"], pts, strict=True):
        n2, e2, _ = pymap3d.geodetic2ned(lat, lon, 0.0, *origin, 0.0)
        assert abs(n2 - n) < 0.01 and abs(e2 - e) < 0.01
    # the mission done (hold, no mission): its lines stay, no longer active
    m2 = info.build(2.0, _status(None), Directive(0.0, 2, Mode.HOLD), None)
    assert m2["mission"]["active"] is False and m2["mission"]["waypoints"] == m[
        "mission"]["waypoints"]
    assert m2["home"] is None and m2["buoy"] is None
    # the AUV's plan, while there is one
    assert m["auv_plan"] == [] and m2["auv_plan"] == []
    plan_ned = [(-40.0, 310.0), (260.0, 310.0), (260.0, -90.0)]
    m3 = info.build(3.0, None, None, None, AuvPlan(3.0, tuple(plan_ned), "shore:alice"))
    assert len(m3["auv_plan"]) == 3
    for (lat, lon), (n, e) in zip(m3["auv_plan"], plan_ned, strict=True):
        n2, e2, _ = pymap3d.geodetic2ned(lat, lon, 0.0, *origin, 0.0)
        assert abs(n2 - n) < 0.01 and abs(e2 - e) < 0.01
    assert info.build(4.0, None, None, None, AuvPlan(4.0))["auv_plan"] == []  # cleared


def test_map_without_the_buoy_feed_has_no_beacons() -> None:
    cfg = build(RuntimeConfig, {}, "test")
    m = MapInfo(cfg, LocalFrame(41.185, -8.705)).build(0.0, None, None, None)
    assert m["beacons"] == [] and m["listener"] is None and m["mission"] is None
    assert m["geofence"] == {"radius_m": 0.0, "polygon": []}


def _open(cfg: dict[str, Any]) -> Any:
    return zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))


def test_map_is_served_to_all_and_access_answers_operators_only(tmp_path: Path) -> None:
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    users = write_users(tmp_path / "users", {"alice": "op-secret", "bob": "view-secret",
                                              "carol": "no-role"})
    boat = Boat([f'runtime.shore.listen=["{ep}"]', "runtime.shore.vessel=beta",
                 'runtime.shore.auth="usrpwd"', f'runtime.shore.users_file="{users}"',
                 'runtime.shore.operators=["alice"]', 'runtime.shore.viewers=["bob"]'],
                scenario=FOLLOW, log=tmp_path / "boat.log")
    with boats(boat):
        op = connect_when_up(lambda: _open(client_config(ep, user="alice",
                                                         password="op-secret")))
        view = _open(client_config(ep, user="bob", password="view-secret"))
        nobody = _open(client_config(ep, user="carol", password="no-role"))
        try:
            heard: list[dict[str, Any]] = []
            view.declare_subscriber("zarco/*/map",
                                    lambda s: heard.append(json.loads(s.payload.to_bytes())))
            deadline = time.monotonic() + 30.0
            maps: list[Any] = []
            m: dict[str, Any] = {}
            # the boat answers once its link is up, and shows the mission once
            # its autostart's checks have passed
            while time.monotonic() < deadline:
                maps = list(view.get("zarco/beta/map", timeout=2.0))
                if maps and maps[0].ok is not None:
                    m = json.loads(maps[0].ok.payload.to_bytes())
                    if m["mission"] is not None:
                        break
                time.sleep(0.2)
            assert len(maps) == 1 and maps[0].ok is not None
            # the scenario's network (follow_turn: three beacons, the buoy at the first)
            assert m["listener"] == 0 and len(m["beacons"]) == 3
            lat, lon, _ = pymap3d.ned2geodetic(400.0, 50.0, 0.0, m["origin"]["lat_deg"],
                                               m["origin"]["lon_deg"], 0.0)
            assert abs(m["beacons"][1]["lat_deg"] - lat) < 1e-7
            assert abs(m["beacons"][1]["lon_deg"] - lon) < 1e-7
            assert m["mission"] is not None and m["mission"]["kind"] == "follow"
            assert len(list(op.get("zarco/beta/map", timeout=2.0))) == 1
            # the role probe: the operator gets its answer, the others none
            acc = list(op.get("zarco/beta/access", timeout=3.0))
            assert len(acc) == 1 and json.loads(acc[0].ok.payload.to_bytes()) == {
                "role": "operator"}
            assert list(view.get("zarco/beta/access", timeout=1.0)) == []
            assert list(nobody.get("zarco/beta/access", timeout=1.0)) == []
            assert list(nobody.get("zarco/beta/map", timeout=1.0)) == []
            # published too: home becomes known with the first fix (within 10 s)
            deadline = time.monotonic() + 20.0
            while time.monotonic() < deadline and not any(h.get("home") for h in heard):
                time.sleep(0.2)
            assert any(h.get("home") for h in heard), heard[-1:] or "no map heard"
        finally:
            for s in (op, view, nobody):
                s.close()
    assert boat.stop() == 0
