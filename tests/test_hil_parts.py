"""The HIL rig's parts, fast: fault schedule, pseudo-terminal ports, the runtime
configuration it writes, and reading the runtime's status file and log."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
import serial

from drivers.nmea import NmeaFramer, format_sentence
from drivers.sim.faults import FaultPlan, FaultSpec
from hil.ptys import PtyPort
from hil.run import clean_legs, failsafe_entries, pooled_rms, runtime_config, toml_dumps
from hil.runtime_status import ErrorLog, RuntimeStatus
from hil.scenario import load_hil_scenario
from zarco_core.config import ConfigError, build
from zarco_tools.scenario import load_runtime_config
from zarco_tools.sim_report import TrackLog

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "hil" / "scenarios" / "line_faults.toml"
GGA = format_sentence("GNGGA,120000.00,4111.1,N,00842.3,W,4,14,0.7,0.0,M,0.0,M,1.0,0000")
HDG = format_sentence("HCHDG,98.3,,,2.0,W")


def fault(**kw: object) -> FaultSpec:
    return build(FaultSpec, dict(kw), "test")


# ------------------------------------------------------------- fault plan


def test_fault_schedule_is_validated_with_file_and_key(tmp_path: Path) -> None:
    scn, faults = load_hil_scenario(SCENARIO)
    assert [f.kind for f in faults] == ["unplug", "noise", "split", "bad_checksum"]
    assert scn.mission.waypoints == [[0.0, 0.0], [35.0, 0.0]]
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENARIO.read_text().replace('kind = "noise"', 'kind = "nosie"'))
    with pytest.raises(ConfigError, match=r"faults\[1\]\.kind: must be one of"):
        load_hil_scenario(bad)
    buoy = tmp_path / "buoy.toml"  # a lines mission has no buoy feed to break
    buoy.write_text(SCENARIO.read_text() + '\n[[faults]]\nkind = "silence"\ndevice = "buoy"\n')
    with pytest.raises(ConfigError, match=r"faults\[4\]\.device: a buoy fault needs the buoy"):
        load_hil_scenario(buoy)
    with pytest.raises(ConfigError, match=r"runtime\.devices\.buoy\.enabled: the rig serves"):
        load_hil_scenario(SCENARIO, ["runtime.devices.buoy.enabled=true"])
    with pytest.raises(ValueError, match="GPS fault"):
        fault(kind="fix", device="compass")
    with pytest.raises(ValueError, match="must last"):
        fault(kind="unplug", duration_s=0.0)


def test_unplug_silence_and_fix_windows() -> None:
    plan = FaultPlan([fault(kind="unplug", device="gps", at_s=2.0, duration_s=1.0),
                      fault(kind="silence", device="compass", at_s=1.0, duration_s=1.0),
                      fault(kind="fix", fix="rtk_float", at_s=5.0, duration_s=0.0),
                      fault(kind="fix", fix="single", at_s=6.0, duration_s=1.0)])
    assert plan.plugged("gps", 1.99) and not plan.plugged("gps", 2.0)
    assert plan.plugged("gps", 3.0) and plan.plugged("compass", 2.5)
    assert plan.shape("compass", 1.5, HDG) == ([], 0.0)
    assert plan.shape("compass", 2.0, HDG) == ([HDG], 0.0)
    modes = [plan.fix_mode(t, "rtk_fixed") for t in (4.9, 5.0, 6.5, 7.0, 1e5)]
    assert modes == ["rtk_fixed", "rtk_float", "single", "rtk_float", "rtk_float"]
    assert plan.edges() == [1.0, 2.0, 3.0, 5.0, 6.0, 7.0]


def test_damaged_bytes_are_refused_by_the_framer_and_checksum() -> None:
    from drivers.gps_parser import parse_gps
    from drivers.nmea import NmeaError

    plan = FaultPlan([fault(kind="bad_checksum", device="gps", at_s=0.0, duration_s=1.0),
                      fault(kind="truncate", device="gps", at_s=1.0, duration_s=1.0)], seed=3)
    (bad,), _ = plan.shape("gps", 0.5, GGA)
    assert bad != GGA and bad[:-5] == GGA[:-5]
    with pytest.raises(NmeaError) as ei:
        parse_gps(bad.decode().strip(), 0.0)
    assert ei.value.reason == "checksum"
    (cut,), _ = plan.shape("gps", 1.5, GGA)
    assert GGA.startswith(cut) and len(cut) < len(GGA) - 2
    fr = NmeaFramer()
    assert fr.feed(cut + GGA) == [GGA.decode().strip()]  # the cut one is dropped, the next kept


def test_split_writes_rebuild_the_same_stream() -> None:
    plan = FaultPlan([fault(kind="split", device="gps", at_s=0.0, duration_s=9.0,
                            chunk_max_bytes=3, chunk_gap_s=0.002)], seed=1)
    chunks, gap = plan.shape("gps", 1.0, GGA + GGA)
    assert gap == 0.002 and max(map(len, chunks)) <= 3 and b"".join(chunks) == GGA + GGA
    fr = NmeaFramer()
    assert [s for c in chunks for s in fr.feed(c)] == [GGA.decode().strip()] * 2


def test_noise_rate_and_freeze() -> None:
    plan = FaultPlan([fault(kind="noise", device="compass", at_s=1.0, duration_s=1.0,
                            bytes_per_s=5000.0, binary=False),
                      fault(kind="freeze", device="compass", at_s=3.0, duration_s=1.0)])
    junk = b"".join(plan.noise("compass", t / 100, (t + 1) / 100) for t in range(0, 300))
    assert abs(len(junk) - 5000) < 100 and set(junk) <= set(b"$$GPNM,,,,..**0123456789ABCDEF\r\n")
    assert plan.noise("gps", 0.0, 3.0) == b""
    other = format_sentence("HCHDG,12.0,,,2.0,W")
    assert plan.shape("compass", 3.0, HDG) == ([HDG], 0.0)
    assert plan.shape("compass", 3.5, other) == ([HDG], 0.0)  # stuck on the first value
    assert plan.shape("compass", 4.0, other) == ([other], 0.0)


def test_same_seed_same_damage() -> None:
    def damage(seed: int) -> list[bytes]:
        plan = FaultPlan([fault(kind="noise", device="gps", at_s=0.0, duration_s=1.0),
                          fault(kind="truncate", device="gps", at_s=0.0, duration_s=1.0,
                                fraction=0.5)], seed)
        return [plan.noise("gps", 0.0, 0.1)] + [plan.shape("gps", 0.5, GGA)[0][0]
                                                 for _ in range(20)]

    assert damage(4) == damage(4) and damage(4) != damage(5)


# ------------------------------------------------------------------ ports


def test_pty_port_unplug_and_replug_at_the_same_link(tmp_path: Path) -> None:
    port = PtyPort("gps", tmp_path / "dev" / "gps")
    port.plug()
    try:
        link = tmp_path / "dev" / "gps"
        first = os.readlink(link)
        assert first.startswith("/dev/pts/") and not port.attached()
        assert port.write(GGA) == 0 and port.counters["bytes_unheard"] == len(GGA)
        ser = serial.Serial(str(link), 115200, timeout=1.0)
        assert port.attached()
        assert port.write(GGA) == len(GGA)
        assert ser.read(len(GGA)) == GGA
        ser.write(b"$PZTHR,0.0,0.0*4B\r\n")
        time.sleep(0.05)
        assert port.read() == b"$PZTHR,0.0,0.0*4B\r\n"
        port.unplug()
        assert not link.exists() and not link.is_symlink()
        with pytest.raises(serial.SerialException):
            ser.read(1)  # the device vanished under the open port
        ser.close()
        port.plug()
        assert link.is_symlink() and os.path.exists(os.readlink(link))
        ser = serial.Serial(str(link), 115200, timeout=1.0)
        port.write(HDG)
        assert ser.read(len(HDG)) == HDG
        ser.close()
        time.sleep(0.01)
        assert not port.attached()
    finally:
        port.close()
    assert port.counters["plugs"] == 2 and port.counters["unplugs"] == 2


# ---------------------------------------------------- config and the log


@pytest.mark.parametrize("name, devices", [
    ("line_faults.toml", ("gps", "compass", "thrusters")),
    ("follow_short.toml", ("gps", "compass", "thrusters", "buoy")),
])
def test_runtime_config_round_trips_through_toml(tmp_path: Path, name: str,
                                                 devices: tuple[str, ...]) -> None:
    scn, _ = load_hil_scenario(SCENARIO.with_name(name))
    links = {d: f"/run/zarco/dev/{d}" for d in devices}
    path = tmp_path / "zarco.toml"
    path.write_text(toml_dumps(runtime_config(scn, links)))
    cfg, mission = load_runtime_config(path)
    assert cfg.devices.gps.url == "/run/zarco/dev/gps"
    assert cfg.devices.thrusters.url == "/run/zarco/dev/thrusters"
    assert cfg.devices.buoy.enabled == ("buoy" in devices)
    for d in links:  # everything else as in the scenario
        getattr(scn.runtime.devices, d).url = links[d]
    assert cfg == scn.runtime
    assert mission == scn.mission


def test_runtime_status_reads_what_zarco_run_writes(tmp_path: Path) -> None:
    """The status file as ``zarco run --status`` writes it (its own writer, fed
    through the bus): device health from the first snapshot and the health
    events, modes, failsafes, refusals by reason, the final line."""
    from zarco_core.messages import DeviceSummary, Event, MissionProgress, VesselStatus
    from zarco_runtime.runtime import Runtime
    from zarco_runtime.settings import RuntimeConfig
    from zarco_runtime.vessel import StatusFile

    rt = Runtime(RuntimeConfig())
    path = tmp_path / "status.jsonl"
    sf = StatusFile(str(path), rt)
    rst = RuntimeStatus(path)

    def snap(t: float, mode: str, state: str, reason: str, counters: dict[str, int],
             along: float | None = None) -> VesselStatus:
        gps = DeviceSummary(state, reason, None, counters.get("sentences_ok", 0), 0, counters)
        return VesselStatus(t, 1e9 + t, mode, mode != "idle",
                            MissionProgress("lines", "m", 0, 1, False, along, along),
                            [], {"gps": gps}, {}, {})

    pub = rt.bus.publish
    pub(snap(0.0, "idle", "stale", "opened, waiting for data", {}))
    assert rst.poll() == 1 and rst.ready(["gps"]) and not rst.ready(["gps", "buoy"])
    pub(Event(0.2, "fault", "gps: ok", "gps"))
    pub(Event(0.3, "mode", "mode lines: mission m from autostart (was idle)"))
    pub(snap(1.0, "lines", "ok", "", {"sentences_ok": 9}, 0.4))
    pub(Event(5.0, "fault", "gps: disconnected: port closed", "gps"))
    pub(Event(5.1, "fault", "control: non-finite control output; zero thrust", "control"))
    pub(Event(5.9, "failsafe", "position_lost: position estimate invalid; action idle "
                               "(condition since 0.04 s)"))
    pub(Event(5.9, "mode", "mode idle: failsafe position_lost: position estimate invalid "
                           "(was lines)"))
    pub(Event(6.1, "fault", "gps: stale: opened, waiting for data", "gps"))
    pub(Event(6.2, "fault", "gps: ok", "gps"))
    pub(Event(7.0, "failsafe", "position_lost cleared (position estimate invalid)"))
    pub(snap(7.0, "idle", "ok", "", {"bytes": 900, "sentences_ok": 12, "checksum": 2,
                                     "framing": 1, "reconnects": 1, "bytes_discarded": 40}))
    sf.close()
    with path.open("a") as fh:  # a line still being written is left for the next poll
        fh.write('{"kind": "mode", "t": 9.0, "text": "mode ho')
    rst.poll()
    assert rst.final is not None and rst.final["final"] and rst.snapshots == 4
    assert rst.states("gps") == ["stale", "ok", "disconnected", "stale", "ok"]
    assert [tr.reason for tr in rst.transitions][2] == "port closed"
    assert rst.modes == ["idle", "lines", "idle"]
    assert rst.steering_since("lines") is not None and rst.steering_since("idle") is None
    assert failsafe_entries(rst) == ["position_lost: position estimate invalid; action idle"]
    assert len(rst.of_kind("failsafe")) == 2
    dev = rst.devices()["gps"]
    assert dev["dropped"] == {"checksum": 2, "framing": 1} and dev["counters"]["reconnects"] == 1
    with path.open("a") as fh:
        fh.write('ld at 1.0, 2.0: x (was idle)", "source": "supervisor", "wall": 1.0}\nnot json\n')
    rst.poll()
    assert rst.modes[-1] == "hold" and rst.bad_lines == 1
    # an event line may also keep its kind apart from the line's
    rst.feed(['{"kind": "event", "event": "fault", "t": 9.5, "text": "gps: stale: no data", '
              '"source": "gps", "wall": 2.0}'])
    assert rst.state("gps") == "stale" and rst.events[-1].kind == "fault"


def test_error_log_keeps_errors_and_their_tracebacks_only() -> None:
    lines = [
        "2026-06-01 10:00:00,001 DEBUG asyncio: Using selector: EpollSelector",
        "2026-06-01 10:00:05,500 WARNING zarco.gps: gps: disconnected: device reports "
        "readiness to read but returned no data",
        "2026-06-01 10:00:05,501 DEBUG serial_asyncio_fast: Failed to flush serial connection",
        "Traceback (most recent call last):",
        "termios.error: (5, 'Input/output error')",
        "2026-06-01 10:00:06,000 WARNING zarco.compass: compass: dropped '$HCHDG,1*': "
        "checksum: got 00, computed 1C",
    ]
    log = ErrorLog()
    for ln in lines:
        log.feed(ln + "\n")
    assert log.errors == []  # a DEBUG record's traceback is not an error
    log.feed("2026-06-01 10:00:08,000 ERROR zarco.runtime: task crashed\n")
    log.feed("Traceback (most recent call last):\n")
    assert log.errors == ["zarco.runtime: task crashed", "Traceback (most recent call last):"]


def test_legs_with_faults_are_left_out_of_the_clean_figures() -> None:
    log = TrackLog()
    for i in range(300):
        log.add(i * 0.1, 0.0, 0.0, 0.0, i // 100, 0.0, 0.0)  # legs 0, 1, 2: 10 s each
    assert clean_legs(log, [fault(kind="noise", at_s=12.0, duration_s=1.0)]) == [2]
    assert clean_legs(log, [fault(kind="noise", at_s=12.0, duration_s=1.0)], 0.0) == [0, 2]
    legs = [{"leg": 0, "samples": 100, "xtrack_rms_m": 0.03},
            {"leg": 2, "samples": 300, "xtrack_rms_m": 0.05}]
    assert pooled_rms(legs, [0, 2]) == pytest.approx(((100 * 0.03**2 + 300 * 0.05**2) / 400)
                                                     ** 0.5)
    assert pooled_rms(legs, [1]) is None


def test_runtime_jitter_histogram_percentiles() -> None:
    from hil.run import hist_figures

    counts = [0] * 401  # 0.05 ms bins, the last one for everything beyond 20 ms
    counts[3] = 98
    counts[50] = 1
    counts[400] = 1
    f = hist_figures(counts)
    assert f["runtime_periods"] == 100
    assert f["runtime_jitter_p50_ms"] == 0.2 and f["runtime_jitter_p99_ms"] == 2.55
    assert f["runtime_jitter_max_ms"] == ">20"
    assert hist_figures([0] * 401) == {}
