"""The shore view's topics in a recording (``/shore/state``, ``/shore/auv``,
``/foxglove/events``), derived by the writer from a simulated follow run: each
valid against its schema, made of the recorded messages just before it
(read back with mcap's reader), at most ``location_hz``."""

from __future__ import annotations

import bisect
import itertools
import math
from pathlib import Path
from typing import Any

import jsonschema
import pymap3d
import pytest

from zarco_runtime.links.recorder.schema import SHARED_TOPICS
from zarco_tools.log.reader import iter_messages, open_recording
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

ROOT = Path(__file__).resolve().parents[1]
TOPICS = {"/shore/state", "/shore/auv", "/foxglove/events", "/foxglove/vessel",
          "/foxglove/auv"}


@pytest.fixture(scope="module")
def rec(tmp_path_factory: pytest.TempPathFactory) -> Any:
    path = tmp_path_factory.mktemp("rec") / "follow.mcap"
    scn = load_scenario(ROOT / "config" / "scenarios" / "follow_turn.toml",
                        ["scenario.max_duration_s=120", "auv.start_delay_s=10"])
    run_scenario(scn, record=str(path))
    return open_recording(str(path))


def _before(times: list[float], recs: list[dict[str, Any]], t: float) -> list[dict[str, Any]]:
    """The records a derivation at ``t`` may have taken: the last one before ``t``
    and those of the same time (published in the same instant, before or after)."""
    lo = bisect.bisect_left(times, t - 1e-6)
    hi = bisect.bisect_right(times, t + 1e-6)
    out = recs[lo:hi] + ([recs[lo - 1]] if lo > 0 else [])
    assert out, t
    return out


def test_shared_topics_have_their_schemas_and_validate(rec: Any) -> None:
    from mcap.reader import make_reader

    with open(rec.paths[0], "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    by_topic = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    import json

    for topic, (name, schema) in SHARED_TOPICS.items():
        assert by_topic[topic].name == name
        assert json.loads(by_topic[topic].data) == schema
    n: dict[str, int] = {}
    for m in iter_messages(rec, TOPICS):
        jsonschema.validate(m.json(), SHARED_TOPICS[m.topic][1])
        n[m.topic] = n.get(m.topic, 0) + 1
    assert set(n) == TOPICS, n


def test_shore_state_is_made_of_the_records_before_it(rec: Any) -> None:
    off = rec.utc_offset_s
    want = {"/NavState", "/Directive", "/ThrusterCommand", "/VesselStatus", "/shore/state"}
    by: dict[str, list[dict[str, Any]]] = {k: [] for k in want}
    for m in iter_messages(rec, want):
        by[m.topic].append(m.json())
    nav = {round(r["t"], 6): r for r in by["/NavState"]}
    times = {k: [r["t"] for r in v] for k, v in by.items()}
    states = by["/shore/state"]
    assert len(states) > 100
    for s in states[::7]:
        t = s["t"] - off
        n = nav[round(t, 6)]  # the estimate it was made of
        t = n["t"]
        if n["lat_deg"] is None:  # before the first fix (NaN, recorded as null)
            assert s["lat_deg"] is None and not s["pos_valid"]
            continue
        assert s["lat_deg"] == round(n["lat_deg"], 8) and s["lon_deg"] == round(n["lon_deg"], 8)
        assert s["heading_deg"] == round(math.degrees(n["psi_rad"]) % 360.0, 2)
        assert s["speed_mps"] == round(math.hypot(n["vn_mps"], n["ve_mps"]), 3)
        assert any(s["mode"] == d["mode"] and s["reason"] == d["reason"]
                   for d in _before(times["/Directive"], by["/Directive"], t))
        assert any(s["u1"] == round(tc["u1"], 1) and s["u2"] == round(tc["u2"], 1)
                   for tc in _before(times["/ThrusterCommand"], by["/ThrusterCommand"], t))
        assert any(s["armed"] == st["armed"] and s["failsafes"] == st["failsafes"]
                   for st in _before(times["/VesselStatus"], by["/VesselStatus"], t))
        assert s["vessel"] == "zarco"
    # at most location_hz (5 Hz), and not much less from a 20 Hz estimate
    gaps = [b["t"] - a["t"] for a, b in itertools.pairwise(states)]
    assert min(gaps) > 0.19 and sorted(gaps)[len(gaps) // 2] == pytest.approx(0.2, abs=0.01)


def test_shore_auv_is_the_fitted_line_at_its_time(rec: Any) -> None:
    off = rec.utc_offset_s
    o = rec.config["origin"]
    tracks: dict[float, list[dict[str, Any]]] = {}
    auvs = []
    for m in iter_messages(rec, {"/AuvTrack", "/shore/auv"}):
        if m.topic == "/AuvTrack":
            tracks.setdefault(round(m.json()["t"], 3), []).append(m.json())
        else:
            auvs.append(m.json())
    assert len(auvs) > 30
    moving = 0
    for a in auvs[::5]:
        # the track of that time (a new fit and a re-stamped one may share it)
        near = []
        for tr in tracks[round(a["t"] - off, 3)]:
            dt = tr["t"] - tr["t0"]
            n, e = tr["x0_m"] + tr["vx_mps"] * dt, tr["y0_m"] + tr["vy_mps"] * dt
            lat, lon, _ = pymap3d.ned2geodetic(n, e, 0.0, o["lat_deg"], o["lon_deg"],
                                               o["alt_m"])
            near.append(max(abs(a["lat_deg"] - lat), abs(a["lon_deg"] - lon)))
        assert min(near) < 2e-8, near
        assert a["distance_m"] is None or 0.0 <= a["distance_m"] < 200.0
        moving += a["speed_mps"] > 0.5
    assert moving > 0  # the AUV set off


def test_every_event_is_a_log_message(rec: Any) -> None:
    events, logs = [], []
    for m in iter_messages(rec, {"/Event", "/foxglove/events"}):
        (events if m.topic == "/Event" else logs).append(m.json())
    assert len(events) >= 3 and len(logs) == len(events)
    for e, lg in zip(events, logs, strict=True):
        assert lg["message"] == e["text"] and lg["name"] == f"{e['kind']}/{e['source']}"
        assert lg["level"] == (3 if e["kind"] in ("failsafe", "fault") else 2)
        ts = lg["timestamp"]["sec"] + lg["timestamp"]["nsec"] * 1e-9
        assert abs(ts - (e["t"] + rec.utc_offset_s)) < 1e-6
