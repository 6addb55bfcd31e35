"""A real ``zarco run`` on pseudo-terminals records by default, survives ``kill -9``
with at most the last second of its recording lost, and after a restart keeps
the old recording, starts a new one, and knows the last mission (``resume``).

A feeder thread plays the simulated world's GPS, compass and thruster-status
bytes into the ptys at their rates (as HIL does, without the control loop
closed: the boat does not need to move here).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader

from drivers.sim.world import SimWorld
from hil.ptys import PtyPort
from zarco_tools.log.reader import iter_messages, open_recording, recover
from zarco_tools.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
ZARCO = [sys.executable, "-m", "zarco_runtime.cli"]


class Feeder(threading.Thread):
    """The simulated devices behind ptys, in real time."""

    def __init__(self, run_dir: Path) -> None:
        super().__init__(daemon=True)
        scn = load_scenario(ROOT / "config" / "scenarios" / "rectangle.toml")
        self.origin = (scn.world.origin_lat_deg, scn.world.origin_lon_deg)
        self.world = SimWorld(scn.world, 1)
        self.ports = {d: PtyPort(d, run_dir / "dev" / d) for d in ("gps", "compass",
                                                                    "thrusters")}
        for p in self.ports.values():
            p.plug()
        self.stop = threading.Event()

    def _write(self, dev: str, data: bytes) -> None:
        p = self.ports[dev]
        with contextlib.suppress(OSError):  # nobody reading: the bytes are lost
            os.write(p.master, data)

    def run(self) -> None:
        t0 = time.monotonic()
        k = 0
        while not self.stop.is_set():
            k += 1
            t = k * 0.05
            time.sleep(max(0.0, t0 + t - time.monotonic()))
            self.world.advance_to(t)
            self._write("compass", self.world.compass_bytes(t))
            if k % 2 == 0:
                self._write("gps", self.world.gps_bytes(t))
            if k % 4 == 0:
                self._write("thrusters", self.world.thruster_status_bytes(t))
            with contextlib.suppress(OSError):
                os.read(self.ports["thrusters"].master, 65536)  # the runtime's commands


def _ctl(sock: Path, name: str, args: dict[str, object] | None = None) -> dict[str, object]:
    cmd = [*ZARCO, "ctl", "--socket", str(sock), name]
    if args is not None:
        cmd.append(json.dumps(args))
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=20, cwd=ROOT)
    return dict(json.loads(out.stdout or "{}"))


def _arm(sock: Path, timeout: float = 15.0) -> bool:
    """Arm as an operator does: again until the boat is ready and accepts."""
    return _wait(lambda: _ctl(sock, "arm").get("ok"), timeout)


def _wait(pred: object, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():  # type: ignore[operator]
            return True
        time.sleep(0.1)
    return False


def _start(cfg: Path, log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen([*ZARCO, "run", "--config", str(cfg)], cwd=ROOT,
                            stdout=log.open("ab"), stderr=subprocess.STDOUT,
                            start_new_session=True)


def pty_rig(tmp_path: Path, state_file: str) -> tuple[Path, Feeder]:
    """A vessel configuration on pseudo-terminals fed by a running :class:`Feeder`
    (skips where there are none): the control socket and a relative recording
    directory in ``tmp_path``, the supervisor's state in ``state_file`` ("" for none)."""
    try:
        a, b = os.openpty()
        os.close(a)
        os.close(b)
    except OSError as exc:  # pragma: no cover
        pytest.skip(f"no pseudo-terminals here: {exc}")
    feeder = Feeder(tmp_path)
    feeder.start()
    lat, lon = feeder.origin
    cfg = tmp_path / "zarco.toml"
    cfg.write_text(f"""
[origin]
lat_deg = {lat}
lon_deg = {lon}
[devices.gps]
url = "{feeder.ports['gps'].link}"
[devices.compass]
url = "{feeder.ports['compass'].link}"
[devices.thrusters]
url = "{feeder.ports['thrusters'].link}"
[supervisor]
state_file = "{state_file}"
control_socket = "{tmp_path / 'ctl.sock'}"
[record]
dir = "recordings"
min_free_mb = 0
""")
    return cfg, feeder


@pytest.fixture()
def rig(tmp_path: Path):  # type: ignore[no-untyped-def]
    cfg, feeder = pty_rig(tmp_path, str(tmp_path / "state" / "state.json"))
    yield tmp_path, cfg, feeder
    feeder.stop.set()


def test_kill_9_restart_keeps_history_and_the_last_mission(rig) -> None:  # type: ignore[no-untyped-def]
    tmp, cfg, feeder = rig
    sock = tmp / "ctl.sock"
    rec_dir = tmp / "recordings"  # relative [record] dir: beside the configuration file
    log = tmp / "runtime.log"
    p1 = _start(cfg, log)
    try:
        assert _wait(lambda: sock.exists() and _ctl(sock, "status").get("mode"), 30), \
            log.read_text()
        assert _wait(lambda: _ctl(sock, "status")["devices"]["gps"]["state"] == "ok",
                     15)
        lat, lon = feeder.origin
        assert _arm(sock)
        ack = _ctl(sock, "mission", {"waypoints": [[lat, lon], [lat + 0.0005, lon]],
                                     "speed_mps": 1.0, "start": True, "name": "north"})
        assert ack["ok"], ack
        time.sleep(2.0)
        killed_at = time.time()
        os.killpg(p1.pid, signal.SIGKILL)  # the runtime and its recorder's writer
        p1.wait(timeout=10)
    finally:
        if p1.poll() is None:
            os.killpg(p1.pid, signal.SIGKILL)
    (first,) = sorted(rec_dir.glob("*.mcap"))
    # mcap's own streaming reader reads the unfinished file up to its torn end
    n = 0
    with first.open("rb") as fh, pytest.raises(EndOfFile):
        for _ in NonSeekingReader(fh).iter_messages(log_time_order=False):
            n += 1
    assert n > 100
    rec = open_recording(str(first))
    last_ns = max(m.log_ns for m in iter_messages(rec))
    # it holds what came before the kill (how much of the last second is lost is the
    # benchmark's figure, tests/bench/record.py: a loaded machine delays the writer)
    assert rec.truncated and last_ns / 1e9 <= killed_at, (last_ns, rec.truncated)
    assert any(m.topic == "/raw/gps/rx" for m in iter_messages(rec, {"/raw/gps/rx"}))
    fixed = tmp / "fixed.mcap"
    k, why = recover(str(first), str(fixed))
    assert k == n and why

    # restart: a new file, the old one untouched, the mission still known
    size = first.stat().st_size
    p2 = _start(cfg, log)
    try:
        assert _wait(lambda: sock.exists() and _ctl(sock, "status").get("mode"), 30)
        assert _wait(lambda: _ctl(sock, "status")["devices"]["gps"]["state"] == "ok",
                     15)
        assert _ctl(sock, "resume", {})["reason"] == "disarmed"  # a restart boots disarmed
        assert _arm(sock)
        ack = _ctl(sock, "resume", {})
        assert ack["ok"] and ack["mode"] == "lines", ack
        time.sleep(0.5)
        p2.send_signal(signal.SIGTERM)
        assert p2.wait(timeout=20) == 0
    finally:
        if p2.poll() is None:
            os.killpg(p2.pid, signal.SIGKILL)
    files = sorted(rec_dir.glob("*.mcap"))
    assert len(files) == 2 and first in files and first.stat().st_size == size
    second = open_recording(str(files[1] if files[0] == first else files[0]))
    events = [m.json() for m in iter_messages(second, {"/Event", "/CommandAck"})]
    assert second.finished and all(second.finished.values()) and not second.truncated
    assert any("last mission 'north' can be resumed" in str(e.get("text")) for e in events)
    assert any(e.get("name") == "resume" and e.get("ok") for e in events)
    meta = second.metadata
    assert json.loads(meta["config"])["supervisor"]["state_file"].endswith("state.json")
    assert meta["version"]
