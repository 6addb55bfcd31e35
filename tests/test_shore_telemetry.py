"""The shore telemetry objects built from bus messages: AUV position from the
track's line model, distance from the vessel, status from the track flags,
degrees clockwise from north, and null (not NaN) for what is not known."""

from __future__ import annotations

import json
import math

from zarco_core.auv_messages import AuvTrack, TrackFlags
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import FixQuality, GuidanceStatus, Mode, NavState, ThrusterCommand
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.shore import telemetry

FRAME = LocalFrame(41.185, -8.705)


def _track(flags: int, t: float = 15.0, lost: bool = False, vx: float = 1.0,
           vy: float = 0.0) -> AuvTrack:
    psi = math.atan2(vy, vx)
    return AuvTrack(t=t, x0_m=100.0, y0_m=50.0, vx_mps=vx, vy_mps=vy, psi_auv_rad=psi,
                    v_auv_mps=math.hypot(vx, vy), h_auv_m=0.0, cov=(0.0,) * 16, t0=10.0,
                    t0_utc_s=0.0, fix_age_s=1.0, flags=flags, lost=lost, kf_x_m=0.0,
                    kf_y_m=0.0, kf_vx_mps=0.0, kf_vy_mps=0.0, kf_pos_sigma_m=1.0)


def _nav(x: float, y: float, t: float = 15.0, psi: float = 0.0) -> NavState:
    lat, lon, _ = FRAME.to_geodetic(x, y)
    return NavState(t=t, x_m=x, y_m=y, vn_mps=0.0, ve_mps=-0.5, psi_rad=psi, r_rps=0.0,
                    u_mps=0.0, v_mps=0.0, lat_deg=lat, lon_deg=lon, fix=FixQuality.RTK_FIXED,
                    pos_valid=True, heading_valid=True)


def test_auv_position_is_the_line_model_at_the_message_time() -> None:
    # 5 s after t0 at 1 m/s north: 105 m north, 50 m east; the vessel at 101 m, 47 m
    a = telemetry.auv(1.0e9, _track(int(TrackFlags.INITIALISED)), FRAME,
                      _nav(101.0, 47.0, t=15.0))
    lat, lon, _ = FRAME.to_geodetic(105.0, 50.0)
    assert abs(a["lat_deg"] - lat) < 1e-8 and abs(a["lon_deg"] - lon) < 1e-8
    # 105 m north of a 41.185° origin is 0.000945° of latitude
    assert abs(a["lat_deg"] - (41.185 + 105.0 / 111_090.0)) < 2e-6
    assert a["distance_m"] == 5.0  # a 3-4-5 triangle
    assert a["course_deg"] == 0.0 and a["speed_mps"] == 1.0 and a["status"] == "tracking"


def test_auv_course_is_clockwise_from_north_in_0_360() -> None:
    west = telemetry.auv(0.0, _track(int(TrackFlags.INITIALISED), vx=0.0, vy=-1.0), FRAME,
                         None)
    assert west["course_deg"] == 270.0 and west["distance_m"] is None


def test_auv_carries_the_sound_speed_estimate_and_its_sigma() -> None:
    tr = _track(int(TrackFlags.INITIALISED))
    tr.sound_speed_mps, tr.sound_speed_sigma_mps = 1486.4213, 0.6149
    a = telemetry.auv(0.0, tr, FRAME, None)
    assert a["sound_speed_mps"] == 1486.42 and a["sound_speed_sigma_mps"] == 0.61
    # a track built without them (NaN) says null, never NaN
    b = json.loads(json.dumps(telemetry.auv(0.0, _track(int(TrackFlags.INITIALISED)), FRAME,
                                            None), allow_nan=False))
    assert b["sound_speed_mps"] is None and b["sound_speed_sigma_mps"] is None


def test_auv_status_from_flags() -> None:
    f = TrackFlags
    cases = [(f.NONE, False, "acquiring"), (f.INITIALISED | f.TURNING, False, "turning"),
             (f.INITIALISED | f.STALE, False, "stale"), (f.INITIALISED, True, "lost"),
             (f.INITIALISED | f.LOST, False, "lost")]
    for flags, lost, want in cases:
        assert telemetry.auv_status(int(flags), lost) == want


def test_state_before_anything_is_known_is_valid_json_with_nulls() -> None:
    st = telemetry.state("v1", 1.7e9, 3.0, None, None, None, None, None)
    text = json.dumps(st, allow_nan=False)  # no NaN anywhere
    assert json.loads(text)["lat_deg"] is None and st["mode"] == "idle"
    assert st["leg"] is None and st["legs"] == 0 and st["u1"] == 0.0


def test_state_from_the_bus() -> None:
    nav = _nav(10.0, 20.0, t=2.9, psi=-math.pi / 2)
    g = GuidanceStatus(2.95, "lines", 2, 4, 12.0, -0.25, 0.0, 1.0)
    st = telemetry.state("v1", 1.7e9, 3.0, nav, g, ThrusterCommand(2.95, 40.0, 60.0),
                         Directive(2.0, 3, Mode.LINES, reason="mission x"), None)
    assert st["heading_deg"] == 270.0 and st["course_deg"] == 270.0  # west
    assert st["speed_mps"] == 0.5 and st["fix"] == "rtk_fixed"
    assert (st["leg"], st["legs"], st["xtrack_m"]) == (2, 4, -0.25)
    assert (st["u1"], st["u2"], st["mode"]) == (40.0, 60.0, "lines")
    # guidance older than a second no longer describes the mission
    stale = telemetry.state("v1", 1.7e9, 4.5, nav, g, None, None, None)
    assert stale["leg"] is None and stale["xtrack_m"] is None


def test_auv_position_covariance_is_the_line_models_at_the_message_time() -> None:
    import numpy as np

    rng = np.random.default_rng(7)
    for dt in (0.0, 0.4, 5.0, 30.0):
        a = rng.normal(size=(4, 4))
        c = a @ a.T + np.diag([4.0, 9.0, 0.01, 0.02])  # a valid (x0, y0, vx, vy) covariance
        tr = _track(int(TrackFlags.INITIALISED), t=10.0 + dt)
        tr.cov = tuple(float(v) for v in c.ravel())
        got = telemetry.auv(0.0, tr, FRAME, None)["pos_cov_m2"]
        j = np.array([[1.0, 0.0, dt, 0.0], [0.0, 1.0, 0.0, dt]])  # ∂(x, y)/∂(x0, y0, vx, vy)
        want = j @ c @ j.T
        assert np.allclose(got, [want[0, 0], want[0, 1], want[1, 1]], atol=1e-4), (dt, got)
    assert telemetry.auv(0.0, _track(int(TrackFlags.INITIALISED)), FRAME, None)[
        "pos_cov_m2"] == [0.0, 0.0, 0.0]
    short = _track(int(TrackFlags.INITIALISED))
    short.cov = ()
    assert telemetry.auv(0.0, short, FRAME, None)["pos_cov_m2"] is None
    nan = _track(int(TrackFlags.INITIALISED))
    nan.cov = (math.nan,) * 16
    assert json.dumps(telemetry.auv(0.0, nan, FRAME, None)["pos_cov_m2"]) == "[null, null, null]"
