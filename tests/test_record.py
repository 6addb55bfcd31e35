"""The recorder on simulations: everything on the bus and every raw device chunk is
in the MCAP file with a JSON schema per type; the Foxglove map topics are there;
a replay of the raw bytes and the thruster commands sent gives back the
navigation and the AUV track exactly, and a tuning change shows;
rotation, the free-space floor and a stalled writer never stop the runtime."""

from __future__ import annotations

import base64
import io
import itertools
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from zarco_core.auv_messages import AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock, run_virtual
from zarco_core.messages import Event, Fault, NavState
from zarco_runtime.links.recorder.recorder import Recorder
from zarco_runtime.links.recorder.writer import Options, Recording
from zarco_runtime.settings import RuntimeConfig
from zarco_tools.log.export import export
from zarco_tools.log.info import summarize
from zarco_tools.log.plot import collect, plot_recording
from zarco_tools.log.reader import iter_messages, open_recording
from zarco_tools.log.replay import replay, report
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import SimResult, run_scenario

ROOT = Path(__file__).resolve().parents[1]


def _follow(path: Path, seconds: float = 150.0) -> SimResult:
    scn = load_scenario(ROOT / "config" / "scenarios" / "follow_turn.toml",
                        [f"scenario.max_duration_s={seconds}"])
    return run_scenario(scn, record=str(path))


@pytest.fixture(scope="module")
def follow(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SimResult]:
    path = tmp_path_factory.mktemp("rec") / "follow.mcap"
    return path, _follow(path)


def test_every_message_and_raw_chunk_is_recorded_with_a_schema(follow: Any) -> None:
    path, res = follow
    with path.open("rb") as fh:  # a finished file: mcap's indexed reader
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        topics = Counter(ch.topic for _s, ch, _m in reader.iter_messages())
        for ch in summary.channels.values():
            sc = summary.schemas[ch.schema_id]
            assert ch.message_encoding == "json" and sc.encoding == "jsonschema"
            assert json.loads(sc.data)["type"] == "object"
    nav = summary.schemas[next(c.schema_id for c in summary.channels.values()
                               if c.topic == "/NavState")]
    props = json.loads(nav.data)["properties"]
    assert set(props) == set(NavState.__slots__)  # type: ignore[attr-defined]
    assert props["x_m"]["type"] == "number" and props["pos_valid"]["type"] == "boolean"
    assert {c["title"] for c in props["fix"]["oneOf"]} >= {"RTK_FIXED", "NONE"}
    runtime = res.extra["runtime"]
    # every bus message: what the bus published, the recording holds (plus its own
    # raw and derived topics)
    bus_topics = {t: n for t, n in topics.items()
                  if not t.startswith(("/raw/", "/foxglove/", "/shore/"))}
    after = [e for e in res.extra["events"] if e.text.startswith("recording closed")]
    assert len(after) == 1  # told once the file is finished: the only one not in it
    assert sum(bus_topics.values()) == runtime.bus.published - 1
    for name in ("NavState", "GpsFix", "Heading", "ThrusterCommand", "AuvFix", "AuvTrack",
                 "AcousticEvent", "VesselStatus", "Directive", "SimTruth"):
        assert topics[f"/{name}"] > 0, name
    # every raw byte each driver read, and every command written
    rec = open_recording(str(path))
    raw: Counter[str] = Counter()
    for m in iter_messages(rec, {"/raw/gps/rx", "/raw/compass/rx", "/raw/buoy/rx",
                                 "/raw/thrusters/tx"}):
        d = m.json()
        raw[m.topic] += len(base64.b64decode(d["data"]))
        assert d["utc_s"] == pytest.approx(d["t"] + rec.utc_offset_s)
    for dev in ("gps", "compass", "buoy"):
        assert raw[f"/raw/{dev}/rx"] == res.report["devices"][dev]["bytes"], dev
    tx = sum(1 for _ in iter_messages(rec, {"/raw/thrusters/tx"}))
    assert tx == res.report["devices"]["thrusters"]["commands_sent"]
    meta = rec.metadata
    assert json.loads(meta["config"])["devices"]["gps"]["url"] == "sim://gps"
    assert meta["version"] and meta["clock"] == "virtual"


def test_foxglove_map_topics(follow: Any) -> None:
    path, _res = follow
    rec = open_recording(str(path))
    msgs = list(iter_messages(rec, {"/foxglove/vessel", "/foxglove/auv", "/NavState"}))
    vessel = [m for m in msgs if m.topic == "/foxglove/vessel"]
    auv = [m for m in msgs if m.topic == "/foxglove/auv"]
    assert vessel and auv
    assert {m.schema for m in vessel + auv} == {"foxglove.LocationFix"}
    nav = {round(m.json()["t"], 6): m.json() for m in msgs if m.topic == "/NavState"}
    for m in vessel[::50]:
        fix = m.json()
        ts = fix["timestamp"]["sec"] + fix["timestamp"]["nsec"] * 1e-9
        n = nav[round(ts - rec.utc_offset_s, 6)]  # the estimate it was made of
        assert fix["latitude"] == pytest.approx(n["lat_deg"], abs=1e-12)
        assert fix["longitude"] == pytest.approx(n["lon_deg"], abs=1e-12)
        assert len(fix["position_covariance"]) == 9 and fix["position_covariance_type"] == 3
    # the AUV marker is the tracker's filtered position, about the origin
    o = json.loads(rec.metadata["config"])["origin"]
    a = auv[-1].json()
    assert abs(a["latitude"] - o["lat_deg"]) < 0.01 and abs(a["longitude"] - o["lon_deg"]) < 0.01
    # 5 Hz at most (location_hz)
    ts = [m.log_ns / 1e9 for m in vessel]
    assert min(b - a for a, b in itertools.pairwise(ts)) >= 0.2 - 1e-6


def _exact(r: dict[str, Any], *keys: str) -> None:
    for key in keys:
        assert r[key]["exact"], (key, r[key])
        assert r[key]["recorded"] > 10, (key, r[key])


def test_replay_reproduces_navigation_and_auv_track_exactly(follow: Any) -> None:
    path, _res = follow
    res = replay(open_recording(str(path)))
    r = report(res)
    _exact(r, "nav", "auv_fix", "auv_track")
    # the estimator's command input is the recorded commands, each once: the
    # replay's control task publishes none of its own
    _exact(r, "thruster_commands")
    assert sum(abs(c.u1) + abs(c.u2) > 0 for c in res.commands) > 100
    assert r["thruster_bytes"]["identical"]  # and the driver wrote them again
    # every input at its recorded time (virtual clock: no restamping to do)
    assert r["late"] == r["lost"] == r["restamped"] == 0 and not r["cut_short"]
    assert r["inputs"]["rx:buoy"] > 100 and r["inputs"]["/ThrusterCommand"] > 1000


def test_replay_judges_a_tuning_change_on_the_recorded_inputs(follow: Any) -> None:
    """A tuning changes what the tuned part makes of the same inputs, and nothing
    else: the estimator still takes the commands the boat sent, not commands
    recomputed from its new estimate."""
    path, _res = follow
    rec = open_recording(str(path))
    r = report(replay(rec, ["runtime.ekf.gps_latency_s=0.05"]))
    nav = r["nav"]
    assert nav["different"] > 0.9 * nav["recorded"] and 0.0 < nav["position_rms_m"] < 1.0
    _exact(r, "thruster_commands", "auv_fix", "auv_track")  # the tracker reads no estimate
    r = report(replay(rec, ["tracker.timing_sigma_s=0.002"]))
    assert not r["auv_track"]["exact"] and not r["auv_fix"]["exact"]
    _exact(r, "nav", "thruster_commands")


def test_replay_keeps_the_recorded_order_within_an_instant(
        follow: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """GPS and compass chunks of one instant, played the other way round, give
    another estimate (the compass publishes NavState at once): the exactness
    above rests on the recorded order, which the replay follows."""
    import zarco_tools.log.replay as rp

    load = rp.load_inputs

    def gps_last(rec: Any) -> rp.Inputs:
        inp = load(rec)
        inp.events.sort(key=lambda e: (e[0], e[1] == "gps"))  # stable
        return inp

    monkeypatch.setattr(rp, "load_inputs", gps_last)
    r = report(replay(open_recording(str(follow[0]))))
    assert not r["nav"]["exact"] and r["nav"]["different"] > 100
    _exact(r, "thruster_commands", "auv_fix", "auv_track")


def test_info_export_and_plot_read_the_recording(follow: Any, tmp_path: Path) -> None:
    path, res = follow
    rec = open_recording(str(path))
    s = summarize(rec)
    assert s["finished"] and s["duration_s"] == pytest.approx(150.0, abs=0.5)
    assert s["topics"]["/GpsFix"]["rate_hz"] == pytest.approx(20.0, rel=0.01)
    assert any("mode follow" in e["text"] for e in s["mode_changes"])
    buf = io.StringIO()
    n = export(rec, "/NavState", buf)
    rows = buf.getvalue().splitlines()
    assert n == s["topics"]["/NavState"]["count"] == len(rows) - 1
    assert rows[0].startswith("log_utc_s,t,x_m,y_m")
    f = collect(rec)
    # the same track the simulation logged for its own plot
    assert f.kind == "follow" and f.truth
    assert f.log.x == res.log.x and f.log.t == res.log.t
    assert [a[1:] for a in f.extra["auv_log"]] == [a[1:] for a in res.extra["auv_log"]]
    # the tracker's sound speed and its σ are in the recording as the bus had them,
    # and the plot draws them
    recorded = [(m.sound_speed_mps, m.sound_speed_sigma_mps, m.sound_speed_converged)
                for m in f.extra["auv_msgs"] if isinstance(m, AuvTrack)]
    on_bus = [(m.sound_speed_mps, m.sound_speed_sigma_mps, m.sound_speed_converged)
              for m in res.extra["auv_msgs"] if isinstance(m, AuvTrack)]
    assert recorded == on_bus and len(recorded) > 50
    assert all(1400.0 < c < 1600.0 and 0.0 < sg < 10.5 for c, sg, _ in recorded)
    png = tmp_path / "follow.png"
    plot_recording(rec, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def rectangle(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """A lines mission recorded in parts of 1 MB."""
    tmp = tmp_path_factory.mktemp("rect")
    scn = load_scenario(ROOT / "config" / "scenarios" / "rectangle.toml",
                        ["scenario.max_duration_s=120", "runtime.record.max_file_mb=1"])
    path = tmp / "rect.mcap"
    run_scenario(scn, record=str(path))
    return [path, *sorted(tmp.glob("rect-*.mcap"))]


def test_rotation_parts_are_finished_and_continuous(rectangle: list[Path]) -> None:
    parts = rectangle
    assert len(parts) >= 2 and parts[1].name == "rect-002.mcap"
    rec = open_recording([str(p) for p in parts])
    t = [m.json()["t"] for m in iter_messages(rec, {"/SimTruth"})]
    assert all(rec.finished.values()) and not rec.truncated
    assert t == pytest.approx([0.1 * (k + 1) for k in range(len(t))]) and t[-1] > 119.0
    for p in parts:
        meta = open_recording(str(p)).metadata
        assert meta["part"] == str(parts.index(p) + 1) and "config" in meta


def test_replay_of_a_lines_mission_in_parts_is_exact(rectangle: list[Path]) -> None:
    rec = open_recording([str(p) for p in rectangle])
    r = report(replay(rec))
    _exact(r, "nav", "thruster_commands")
    assert r["thruster_bytes"]["identical"] and r["late"] == r["lost"] == 0
    assert r["auv_track"]["recorded"] == r["auv_track"]["replayed"] == 0  # no AUV here
    r = report(replay(rec, ["ekf.thrust_model=false"]))  # the estimator without the commands
    assert not r["nav"]["exact"] and r["nav"]["position_rms_m"] > 0.0
    _exact(r, "thruster_commands")


def test_disk_floor_stops_recording_with_a_fault_not_the_run(tmp_path: Path) -> None:
    scn = load_scenario(ROOT / "config" / "scenarios" / "rectangle.toml",
                        ["scenario.max_duration_s=20", "runtime.record.min_free_mb=1e7"])
    # as on the boat: the recorder stops, the runtime goes on to its end
    res = run_scenario(scn, record=str(tmp_path / "full.mcap"), end_on_record_failure=False)
    assert res.report["stop"].startswith("time limit")  # the run went on to its end
    events = [e for e in res.extra["events"] if e.source == "recorder"]
    assert any(e.kind == "fault" and "below the floor" in e.text for e in events), events
    assert not (tmp_path / "full.mcap").exists()
    # zarco sim: a recording asked for and not written ends the run, and says why.
    # The writer is a process of its own: when its word reaches the simulation's
    # virtual clock depends on the machine's load (6 s alone, 10 s on a loaded
    # machine), so the limit here is far off and the stop reason is what counts
    scn = load_scenario(ROOT / "config" / "scenarios" / "rectangle.toml",
                        ["scenario.max_duration_s=120", "runtime.record.min_free_mb=1e7"])
    res = run_scenario(scn, record=str(tmp_path / "full.mcap"))
    assert res.report["stop"].startswith("recording failed at ")
    assert res.report["sim_seconds"] < 120.0 and "below the floor" in res.extra["record_error"]
    assert res.extra["record_paths"] == [] and not (tmp_path / "full.mcap").exists()


def _batch(n: int, t0: float, ch: int = 1) -> bytes:
    from zarco_runtime.links.recorder.schema import packer
    from zarco_runtime.links.recorder.writer import BATCH

    records = [{"t": t0 + k, "v": k} for k in range(n)]
    return BATCH.pack(n, 1000.0) + packer().encode(([ch] * n, records))


def test_writer_floor_mid_run_keeps_what_is_written(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Free space falls below the floor after some chunks: the file is finished with
    everything written so far, and nothing more is taken."""
    import zarco_runtime.links.recorder.writer as w

    free = [1000.0]
    monkeypatch.setattr(w, "free_mb", lambda path: free[0])
    monkeypatch.setattr(w, "emit", lambda ev, **kw: events.append((ev, kw)))
    events: list[tuple[str, dict[str, Any]]] = []
    rec = Recording(Options(dir=str(tmp_path), base="run", min_free_mb=100.0, flush_s=0.0))
    rec.add_channel({"id": 1, "topic": "/x", "schema_name": "x", "schema": "{}"})
    rec.batch(memoryview(_batch(10, 0.0)))
    rec.tick(force=True)
    free[0] = 50.0
    rec.batch(memoryview(_batch(10, 10.0)))
    rec.tick(force=True)  # this chunk is written, then the floor is seen
    rec.batch(memoryview(_batch(10, 20.0)))  # refused
    rec.close()
    assert [e for e, _ in events] == ["open", "close", "disk_low"]
    (f,) = tmp_path.glob("*.mcap")
    r = open_recording(str(f))
    assert [m.json()["v"] for m in iter_messages(r)] == list(range(10)) * 2
    assert all(r.finished.values()) and rec.dropped == 10


def test_a_stalled_writer_never_blocks_the_publisher() -> None:
    """Real time: batches a writer cannot take wait in a bounded queue and the
    oldest are dropped, counted, with a fault; publishing never waits."""
    cfg = RuntimeConfig()
    cfg.record.queue_mb = 1.0
    bus = Bus()
    faults: list[Fault] = []
    bus.listen(Fault, faults.append)
    events: list[Event] = []
    bus.listen(Event, events.append)

    async def main() -> Recorder:
        rec = Recorder(cfg, bus, Clock(utc_offset_s=0.0))
        for k in range(20000):  # about 4 MB of NavState, never handed to a writer
            bus.publish(NavState(k * 0.01, 1.0, 2.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 41.0,
                                 -8.0, 4, True, True, tuple(float(i) for i in range(25))))
            if k % 1000 == 999:
                rec._batch()
        return rec

    rec = run_virtual(main())
    assert rec.counters["dropped"] > 0 and rec.out_bytes <= 1e6
    assert rec.counters["messages"] == 20000 + len(faults) + len(events)  # all taken
    assert faults and "dropped" in faults[0].reason and math.isfinite(faults[0].t)


def test_a_run_stopped_before_its_first_flush_keeps_its_messages(tmp_path: Path) -> None:
    """Real time: the runtime stops before the recorder's first hand-over (a start
    ended at once): the types first seen in the last batch get their channels, and
    the finished file holds every message."""
    import asyncio
    import contextlib

    cfg = RuntimeConfig()
    cfg.record.dir = str(tmp_path)
    cfg.record.flush_s = 60.0  # no hand-over before the stop
    bus = Bus()

    async def main() -> None:
        rec = Recorder(cfg, bus, Clock(utc_offset_s=0.0))
        task = asyncio.create_task(rec.run())
        await asyncio.sleep(0.2)
        for k in range(5):
            bus.publish(Event(float(k), "mission", f"event {k}", "test"))
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task

    asyncio.run(main())
    (f,) = tmp_path.glob("*.mcap")
    r = open_recording(str(f))
    texts = [m.json()["text"] for m in iter_messages(r) if m.topic == "/Event"]
    assert texts == [f"event {k}" for k in range(5)]


def test_a_killed_writer_leaves_a_file_every_reader_reads_to_its_cut(tmp_path: Path) -> None:
    """kill -9 of the writer at random moments while it writes: the file always
    ends in a cut record (EndOfFile for mcap's streaming reader), never in a record
    no reader can skip, and holds what was flushed."""
    import os
    import random
    import signal
    import struct
    import subprocess
    import sys
    import time

    from mcap.exceptions import EndOfFile
    from mcap.reader import NonSeekingReader

    import zarco_runtime.links.recorder.writer as w
    from zarco_runtime.links.recorder.schema import packer

    def frame(kind: bytes, body: bytes) -> bytes:
        return struct.pack("<cI", kind, len(body)) + body

    rng = random.Random(7)
    pack = packer().encode
    for k in range(4):
        path = tmp_path / f"kill{k}.mcap"
        proc = subprocess.Popen([sys.executable, w.__file__], stdin=subprocess.PIPE,
                                stdout=subprocess.DEVNULL)
        assert proc.stdin is not None
        start = {"op": "start", "file": str(path), "flush_s": 0.05, "fsync_s": 1.0}
        proc.stdin.write(frame(b"J", json.dumps(start).encode()))
        proc.stdin.write(frame(b"J", json.dumps({"op": "channel", "id": 1, "topic": "/x",
                                                  "schema_name": "x", "schema": "{}"}).encode()))
        t = 0.0

        def write_batch(stdin: Any) -> None:
            nonlocal t
            recs = [{"t": (t := t + 0.001), "pad": os.urandom(48).hex()} for _ in range(500)]
            stdin.write(frame(b"D", w.BATCH.pack(500, 1e9) + pack(([1] * 500, recs))))
            stdin.flush()

        # the random moment is counted from the first chunk on disk, however long a
        # loaded machine takes to start the writer
        deadline = time.monotonic() + 120.0
        while not (path.exists() and path.stat().st_size > 4096):
            assert time.monotonic() < deadline, "the writer never wrote a chunk"
            write_batch(proc.stdin)
        end = time.monotonic() + 0.3 * rng.random()
        while time.monotonic() < end:
            write_batch(proc.stdin)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        n = 0
        with path.open("rb") as fh:
            try:
                for _ in NonSeekingReader(fh).iter_messages(log_time_order=False):
                    n += 1
            except EndOfFile:  # the cut: every message before it was read
                pass
            except struct.error:
                # a cut inside a message index's fixed fields: mcap's reader
                # fails on the short read instead of raising EndOfFile; it is
                # still the cut (the reader is at the file's end), not a record
                # it could not skip in the middle
                assert fh.tell() == path.stat().st_size
        assert n > 0
