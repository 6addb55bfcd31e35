"""``zarco run`` as on the vessel, on pseudo-terminals: it owns its devices (locks,
exclusive ports), refuses what cannot run with one line and exit 2, loads no
simulator/HIL/plotting/evaluation code, and every stop signal leaves zero
thrust as the last command on the wire."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from drivers.nmea import NmeaFramer
from drivers.thruster_protocol import encode_pzths, parse_pzthr

BIN = Path(sys.executable).with_name("zarco")


class Pty:
    """A device end: the master side of a raw pseudo-terminal."""

    def __init__(self) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(self.master, False)

    def read(self) -> bytes:
        out = b""
        while True:
            try:
                chunk = os.read(self.master, 4096)
            except OSError as exc:
                if exc.errno in (errno.EAGAIN, errno.EIO):
                    return out
                raise
            if not chunk:
                return out
            out += chunk

    def close(self) -> None:
        os.close(self.master)


def _config(tmp: Path, gps: str, compass: str, thrusters: str, extra: str = "") -> Path:
    cfg = tmp / "zarco.toml"
    cfg.write_text(f"""
[devices.gps]
url = "{gps}"
[devices.compass]
url = "{compass}"
[devices.thrusters]
url = "{thrusters}"
[supervisor]
control_socket = "{tmp / 'control.sock'}"
state_file = "{tmp / 'state.json'}"
{extra}
""")
    return cfg


def _run(*args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(BIN), *args], capture_output=True, text=True, timeout=timeout)


# ------------------------------------------------------------ refused at start


@pytest.mark.parametrize(("devices", "key", "why"), [
    (("", "/dev/null", "/dev/zero"), "devices.gps.url", "empty device address"),
    (("foo://bar", "/dev/null", "/dev/zero"), "devices.gps.url", "unknown device scheme"),
    (("sim://gps", "/dev/null", "/dev/zero"), "devices.gps.url", "only in the simulator"),
    (("/dev/null", "/dev/null", "/dev/zero"), "devices.compass.url", "same device as"),
])
def test_a_configuration_that_cannot_run_is_refused_with_one_line(
        tmp_path: Path, devices: tuple[str, str, str], key: str, why: str) -> None:
    cfg = _config(tmp_path, *devices)
    out = _run("run", "--config", str(cfg))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert str(cfg) in lines[0] and key in lines[0] and why in lines[0]


def test_a_config_without_devices_is_refused(tmp_path: Path) -> None:
    cfg = tmp_path / "empty.toml"
    cfg.write_text("[origin]\nlat_deg = 41.0\nlon_deg = -8.0\n")
    out = _run("run", "--config", str(cfg))
    assert out.returncode == 2
    assert "devices.gps.url: empty device address" in out.stderr


def test_a_mission_that_needs_a_disabled_device_is_refused(tmp_path: Path) -> None:
    cfg = _config(tmp_path, "/dev/null", "/dev/zero", "/dev/full", """
[mission]
kind = "lines"
waypoints = [[0.0, 0.0], [10.0, 0.0]]
""")
    text = cfg.read_text().replace("[devices.thrusters]\n",
                                   "[devices.thrusters]\nenabled = false\n")
    cfg.write_text(text)
    out = _run("run", "--config", str(cfg))
    assert out.returncode == 2
    assert "mission.kind: a lines mission needs the thrusters, but " \
           "devices.thrusters.enabled = false" in out.stderr


# --------------------------------------------------------------- a live runtime


@contextlib.contextmanager
def running(tmp: Path, *extra: str) -> Iterator[tuple[subprocess.Popen[str], dict[str, Pty]]]:
    ptys = {n: Pty() for n in ("gps", "compass", "thrusters")}
    cfg = _config(tmp, ptys["gps"].path, ptys["compass"].path, ptys["thrusters"].path)
    p = subprocess.Popen([str(BIN), "run", "--config", str(cfg), *extra],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # up when the control socket answers
        end = time.monotonic() + 20.0
        while not (tmp / "control.sock").exists():
            assert p.poll() is None, p.communicate()
            assert time.monotonic() < end, "runtime did not start"
            time.sleep(0.05)
        yield p, ptys
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        for pt in ptys.values():
            pt.close()


def _ctl(tmp: Path, name: str, args: dict[str, object] | None = None) -> dict[str, object]:
    out = _run("ctl", "--socket", str(tmp / "control.sock"), name, json.dumps(args or {}))
    return json.loads(out.stdout)  # type: ignore[no-any-return]


def test_a_second_runtime_on_the_same_devices_is_refused(tmp_path: Path) -> None:
    with running(tmp_path) as (_p, ptys):
        cfg2 = _config(tmp_path / "b" if (tmp_path / "b").mkdir() is None else tmp_path,
                       ptys["gps"].path, ptys["compass"].path, ptys["thrusters"].path)
        out = _run("run", "--config", str(cfg2))
        assert out.returncode == 2
        assert "in use by another zarco runtime (pid" in out.stderr
        assert len(out.stderr.strip().splitlines()) == 1


def test_the_thruster_port_is_opened_exclusively(tmp_path: Path) -> None:
    import fcntl
    import termios

    def probe(path: str) -> subprocess.CompletedProcess[str]:
        """Open the port read-write as an unprivileged user (nobody)."""
        return subprocess.run(["/bin/sh", "-c", f": <> {path}"], user=65534, cwd="/",
                              capture_output=True, text=True, timeout=10)

    # a spare port made first: a pty made after the runtime's are closed could get
    # the thruster port's number while the kernel is still releasing it
    spare = Pty()
    with running(tmp_path) as (_p, ptys):
        path = ptys["thrusters"].path
        os.chmod(path, 0o666)  # as a port the operators' group may open
        end = time.monotonic() + 10.0
        while True:  # wait until the runtime has the port open (flock taken)
            fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                fcntl.flock(fd, fcntl.LOCK_UN)
                busy = False
            except BlockingIOError:
                busy = True
            if busy:
                # TIOCEXCL is set on the tty right after the lock: the kernel says so
                tiocgexcl = getattr(termios, "TIOCGEXCL", 0x80045440)  # Linux _IOR(T, 0x40, int)
                while True:
                    flag = fcntl.ioctl(fd, tiocgexcl, b"\0\0\0\0")
                    if int.from_bytes(flag, sys.byteorder) == 1:
                        break
                    assert time.monotonic() < end, "the thruster port never became exclusive"
                    time.sleep(0.01)
                os.close(fd)
                break
            os.close(fd)
            assert time.monotonic() < end, "the runtime never locked the thruster port"
            time.sleep(0.05)
        # an unprivileged process cannot open it at all (root bypasses TIOCEXCL)
        out = probe(path)
        assert out.returncode != 0
        assert "busy" in out.stderr.lower(), out.stderr
    # a port with the same permissions that no runtime holds opens for that user:
    # the refusal above was the runtime's exclusive open, not the permissions
    os.chmod(spare.path, 0o666)
    assert probe(spare.path).returncode == 0
    spare.close()


def test_zarco_run_loads_no_simulator_hil_plotting_or_evaluation_code(tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPROFILEIMPORTTIME="1")
    ptys = {n: Pty() for n in ("gps", "compass", "thrusters")}
    cfg = _config(tmp_path, ptys["gps"].path, ptys["compass"].path, ptys["thrusters"].path)
    p = subprocess.Popen([str(BIN), "run", "--config", str(cfg)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=env)
    try:
        end = time.monotonic() + 20.0
        while not (tmp_path / "control.sock").exists() and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(1.0)
        p.send_signal(signal.SIGTERM)
        _out, err = p.communicate(timeout=20)
    finally:
        for pt in ptys.values():
            pt.close()
    assert p.returncode == 0, err[-2000:]
    mods = {ln.split("|")[-1].strip() for ln in err.splitlines() if ln.startswith("import time:")}
    assert "zarco_runtime.supervision.supervisor" in mods  # the listing is real
    assert "zarco_runtime.navigation.ekf" in mods
    bad = sorted(m for m in mods if m.split(".")[0] in ("hil", "zarco_tools", "matplotlib")
                 or m.startswith("drivers.sim"))
    assert not bad, bad


class ThrusterController:
    """A fake thruster controller on the master side: answers $PZTHS at 5 Hz and
    records every $PZTHR it receives.  Used as a context manager it answers from
    a thread of its own, all the time, as a real controller does (the runtime's
    ``thruster_silent`` failsafe fires 0.6 s after the last answer, and a loaded
    machine can take longer than that to run a ``zarco ctl``)."""

    def __init__(self, pty: Pty) -> None:
        self.pty = pty
        self.framer = NmeaFramer()
        self.commands: list[tuple[float, float]] = []
        self._next = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> ThrusterController:
        def serve() -> None:
            while not self._stop.is_set():
                self.poll()

        self._thread = threading.Thread(target=serve, name="thruster-controller", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    def wait(self, cond: Callable[[], bool], timeout: float) -> bool:
        """Wait (up to ``timeout`` s) until ``cond()`` holds."""
        end = time.monotonic() + timeout
        while not cond() and time.monotonic() < end:
            time.sleep(0.02)
        return cond()

    def poll(self, dt: float = 0.05) -> None:
        select.select([self.pty.master], [], [], dt)
        for line in self.framer.feed(self.pty.read()):
            with contextlib.suppress(Exception):
                self.commands.append(parse_pzthr(line))
        now = time.monotonic()
        if now >= self._next:
            self._next = now + 0.2
            u1, u2 = self.commands[-1] if self.commands else (0.0, 0.0)
            with contextlib.suppress(OSError):
                os.write(self.pty.master, encode_pzths(u1, u2, 0, 0, 0.0, 0.0))


class Sensors(threading.Thread):
    """The simulated world's GPS and compass bytes into their ptys, in real time (the
    loop is not closed: the boat stays where it is, which is all arming needs)."""

    def __init__(self, gps: Pty, compass: Pty) -> None:
        super().__init__(daemon=True)
        from drivers.sim.world import SimWorld
        from zarco_runtime.settings import Origin
        from zarco_tools.scenario import load_scenario

        scn = load_scenario(Path(__file__).resolve().parents[1] / "config" / "scenarios"
                            / "rectangle.toml")
        o = Origin()  # the vessel file's (the test's configuration sets none)
        scn.world.origin_lat_deg, scn.world.origin_lon_deg = o.lat_deg, o.lon_deg
        self.world = SimWorld(scn.world, 1)
        self.gps, self.compass = gps, compass
        self.stop = threading.Event()

    def run(self) -> None:
        t0 = time.monotonic()
        k = 0
        while not self.stop.is_set():
            k += 1
            t = k * 0.05
            time.sleep(max(0.0, t0 + t - time.monotonic()))
            self.world.advance_to(t)
            with contextlib.suppress(OSError):
                os.write(self.compass.master, self.world.compass_bytes(t))
                if k % 2 == 0:
                    os.write(self.gps.master, self.world.gps_bytes(t))


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT])
def test_every_stop_signal_leaves_zero_thrust_as_the_last_command(
        tmp_path: Path, sig: signal.Signals) -> None:
    with running(tmp_path) as (p, ptys), ThrusterController(ptys["thrusters"]) as ctl:
        sensors = Sensors(ptys["gps"], ptys["compass"])
        sensors.start()
        try:
            assert ctl.wait(lambda: bool(ctl.commands), 30.0), "no $PZTHR from the runtime"
            ack = _ctl(tmp_path, "mode", {"mode": "manual"})  # through `zarco ctl`
            assert ack["reason"] == "disarmed", ack
            end = time.monotonic() + 20.0  # arm as an operator does, once the boat is ready
            while not (ack := _ctl(tmp_path, "arm"))["ok"] and time.monotonic() < end:
                time.sleep(0.2)
            assert ack["ok"], ack
            ack = _ctl(tmp_path, "mode", {"mode": "manual"})
            assert ack["ok"], ack
            # drive: thrust renewed well within the lease, on one socket connection
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                s.connect(str(tmp_path / "control.sock"))
                f = s.makefile("rw")
                end = time.monotonic() + 30.0
                while time.monotonic() < end and ctl.commands[-1:] != [(50.0, -30.0)]:
                    f.write(json.dumps({"name": "thrust", "args": {"u1": 50.0, "u2": -30.0}})
                            + "\n")
                    f.flush()
                    reply = json.loads(f.readline())
                    assert reply["ok"], reply
                    ctl.wait(lambda: ctl.commands[-1:] == [(50.0, -30.0)], 0.1)
            assert ctl.commands[-1] == (50.0, -30.0)  # under way when the signal comes
            p.send_signal(sig)
            _out, err = p.communicate(timeout=30)
            # the controller's thread reads the last bytes on the wire
            ctl.wait(lambda: ctl.commands[-1] == (0.0, 0.0), 5.0)
        finally:
            sensors.stop.set()
        assert p.returncode == 0, err[-2000:]
        assert ctl.commands[-1] == (0.0, 0.0)
        assert f"stopping: {sig.name}" in err
