"""``zarco shore rtcm``: corrections from a file, a TCP server, an NTRIP caster
(a small one on loopback, pygnssutils as the client) and a serial port (a
pseudo-terminal) reach the simulated
boat's GPS driver; only whole valid frames are relayed and counted."""

from __future__ import annotations

import base64
import os
import re
import socket
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path
from typing import Any

from shore_support import Boat, boats, free_port, observer, shore

#: an RTCM3 1005 frame (reference station coordinates), as the standard's example
F1005 = bytes.fromhex("D300133ED7D30202980EDEEF34B4BD62AC0941986F33360B98")
UBX_RESET = bytes.fromhex("B56206040400FFB90200C88F")


def _gps_counters(obs: Any) -> dict[str, int]:
    h = obs.snapshot()["zarco"].health
    return dict(h.get("devices", {}).get("gps", {}).get("counters", {}))


def _has_open(pid: int, path: str) -> bool:
    """Whether process ``pid`` has ``path`` open (its /proc fd links)."""
    try:
        fds = list(Path(f"/proc/{pid}/fd").iterdir())
    except OSError:
        return False
    for fd in fds:
        try:
            if os.readlink(fd) == path:
                return True
        except OSError:
            continue
    return False


def _wait_frames(obs: Any, n: int, timeout_s: float = 30.0) -> dict[str, int]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        c = _gps_counters(obs)
        if c.get("rtcm_frames", 0) >= n:
            time.sleep(1.2)  # one more health period: nothing more arrives
            return _gps_counters(obs)
        time.sleep(0.1)
    raise AssertionError(f"gps counters: {_gps_counters(obs)}")


class Caster:
    """A minimal NTRIP caster on loopback: checks the credentials, streams frames."""

    def __init__(self, mount: str, user: str, password: str, frames: list[bytes]) -> None:
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.port = self.srv.getsockname()[1]
        self.want = "Basic " + base64.b64encode(f"{user}:{password}".encode()).decode()
        self.mount = mount
        self.frames = frames
        self.requests: list[str] = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        conn, _ = self.srv.accept()
        with conn:
            req = conn.recv(4096).decode("latin-1")
            self.requests.append(req)
            auth = [ln.split(":", 1)[1].strip() for ln in req.split("\r\n")
                    if ln.lower().startswith("authorization:")]
            if not req.startswith(f"GET /{self.mount} ") or auth != [self.want]:
                conn.sendall(b"HTTP/1.1 401 Unauthorized\r\n\r\n")
                return
            conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: gnss/data\r\n\r\n")
            time.sleep(0.2)
            for f in self.frames:
                conn.sendall(f)
                time.sleep(0.05)
            time.sleep(3.0)


def test_corrections_from_file_tcp_and_ntrip_reach_the_gps(tmp_path: Path) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    env = {"ZARCO_SHORE_CONNECT": ep}
    boat = Boat([f'runtime.shore.listen=["{ep}"]'], log=tmp_path / "boat.log")
    with boats(boat):
        obs = observer([ep], ["zarco"])
        try:
            # a file: frames with a UBX reset and noise between them
            f = tmp_path / "base.rtcm3"
            f.write_bytes((F1005 + UBX_RESET + b"\x00\xd3\x01garbage") * 20)
            r = shore("rtcm", f"file://{f}", "--rate", "20000", env=env)
            assert r.returncode == 0, r.stderr
            assert "zarco: rtcm 20 frames (500 B) relayed" in r.stdout
            assert "types 1005×20" in r.stdout
            c = _wait_frames(obs, 20)
            assert c["rtcm_frames"] == 20 and c["corrections_bytes"] == 20 * len(F1005)
            # a TCP server (a base station's network port)
            srv = socket.create_server(("127.0.0.1", 0))

            def serve() -> None:
                conn, _ = srv.accept()
                with conn:
                    for _ in range(10):
                        conn.sendall(UBX_RESET + F1005)
                        time.sleep(0.02)

            threading.Thread(target=serve, daemon=True).start()
            r = shore("rtcm", f"tcp://127.0.0.1:{srv.getsockname()[1]}", env=env)
            srv.close()
            assert r.returncode == 0, r.stderr
            assert "10 frames" in r.stdout
            _wait_frames(obs, 30)
            # an NTRIP caster; its credentials from the environment
            caster = Caster("ZARCO0", "base", "pw", [F1005] * 15)
            r = shore("rtcm", f"ntrip://127.0.0.1:{caster.port}/ZARCO0", "--duration", "2.5",
                      env={**env, "ZARCO_NTRIP_USER": "base", "ZARCO_NTRIP_PASSWORD": "pw"})
            assert r.returncode == 0, r.stdout + r.stderr
            # pygnssutils' client drops the first read after the response header (one
            # frame here, sent alone): 14 of the caster's 15 frames
            m = re.search(r"rtcm (\d+) frames", r.stdout)
            assert m is not None and 14 <= int(m.group(1)) <= 15, r.stdout
            n = 30 + int(m.group(1))
            c = _wait_frames(obs, n)
            assert c["rtcm_frames"] == n and c.get("rtcm_bad_frames", 0) == 0
            # a base station on a local serial port (a pseudo-terminal here)
            master, slave = os.openpty()
            tty.setraw(slave)
            tty.setraw(master)

            port = os.ttyname(slave)
            console = subprocess.Popen(
                [sys.executable, "-m", "zarco_runtime.cli", "shore", "rtcm", port,
                 "--baudrate", "57600", "--duration", "6"], stdout=subprocess.PIPE,
                stderr=subprocess.PIPE, text=True, env={**os.environ, **env})
            try:
                # the base station sends once the console has opened the port (a
                # serial port's open drops what arrived before), however long a
                # loaded machine takes to start it
                deadline = time.monotonic() + 60.0
                while not _has_open(console.pid, port) and console.poll() is None:
                    assert time.monotonic() < deadline, "the console never opened the port"
                    time.sleep(0.02)
                for _ in range(12):
                    os.write(master, UBX_RESET + F1005 + b"$GPGGA,noise*00\r\n")
                    time.sleep(0.05)
                out, err = console.communicate(timeout=60)
                r = subprocess.CompletedProcess(console.args, console.returncode, out, err)
            finally:
                if console.poll() is None:
                    console.kill()
                    console.wait()
                os.close(master)
                os.close(slave)
            assert r.returncode == 0, r.stdout + r.stderr
            # pyserial flushes the port's input as the last step of opening it, after
            # the descriptor is open: on a loaded machine the first frame can land
            # before that flush and go, as it would on a real port
            m = re.search(r"rtcm (\d+) frames", r.stdout)
            assert m is not None and 11 <= int(m.group(1)) <= 12, r.stdout
            k = int(m.group(1))
            assert f"types 1005×{k}" in r.stdout, r.stdout
            c = _wait_frames(obs, n + k)
            assert c["rtcm_frames"] == n + k
            # NTRIP credentials on the command line are refused
            r = shore("rtcm", f"ntrip://base:pw@127.0.0.1:{caster.port}/ZARCO0", env=env)
            assert r.returncode == 2 and "not on the command line" in r.stderr
        finally:
            obs.close()
