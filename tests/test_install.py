"""The vessel-computer install (systemd/install.sh) into a scratch root, as a
careful admin checks it: the runtime from a lock with hashes (pip
--require-hashes), the configuration 0640 root:zarco and the shore users file
0600, the unit's DeviceAllow= generated from the configured ports (no
/dev/ptmx, no whole tty classes), ``systemd-analyze verify`` clean and
``systemd-analyze security`` at most 1.5; no upgrade while a real runtime says
the boat is under way (it waits, or asks for --force); uninstall keeps the
recordings and the configuration."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import stat
import subprocess
import sys
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

from zarco_runtime.install import (
    State,
    allow_rules,
    classify,
    from_status,
    render_unit,
    runtime_state,
    serial_path,
)

ROOT = Path(__file__).resolve().parents[1]
LOCK = ROOT / "systemd" / "requirements.lock"
ZARCO = str(Path(sys.executable).with_name("zarco"))
needs_systemd = pytest.mark.skipif(shutil.which("systemd-analyze") is None,
                                   reason="systemd-analyze not installed (.ci/run installs it)")


def _sh(script: str, dest: Path, *args: str, **kw: object) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, DESTDIR=str(dest))
    env.pop("VIRTUAL_ENV", None)
    return subprocess.run(["bash", str(ROOT / "systemd" / script), *args], env=env,
                          capture_output=True, text=True, timeout=900, **kw)  # type: ignore


@pytest.fixture(scope="module")
def dest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("root")
    out = _sh("install.sh", d)
    assert out.returncode == 0, out.stdout + out.stderr
    return d


def _ids(dest: Path, name: str) -> tuple[int, int]:
    pw = (dest / "etc/passwd").read_text()
    m = re.search(rf"^{name}:x:(\d+):(\d+):", pw, re.M)
    assert m is not None, pw
    return int(m.group(1)), int(m.group(2))


# ------------------------------------------------------------------ the tree


@needs_systemd
def test_the_install_tree(dest: Path) -> None:
    zarco = dest / "opt/zarco/bin/zarco"
    assert os.access(zarco, os.X_OK)
    help_ = subprocess.run([str(zarco), "run", "--help"], capture_output=True, text=True)
    assert help_.returncode == 0 and "--config" in help_.stdout
    # runtime dependencies only: no plotting, no test tools
    site = next((dest / "opt/zarco/lib").glob("python3*/site-packages"))
    have = {p.name.lower() for p in site.iterdir()}
    for pkg in ("numpy", "serial", "zenoh", "pymavlink", "mcap"):
        assert any(h.startswith(pkg) for h in have), pkg
    for extra in ("matplotlib", "pytest", "mypy", "ruff", "hypothesis"):
        assert not any(h.startswith(extra) for h in have), extra
    passwd = (dest / "etc/passwd").read_text()
    assert re.search(r"^zarco:x:\d+:\d+:.*:/var/lib/zarco:", passwd, re.M)
    assert re.search(r"^dialout:x:\d+:.*\bzarco\b", (dest / "etc/group").read_text(), re.M)
    assert (dest / "var/lib/zarco/recordings").is_dir()
    assert (dest / "etc/zarco/zarco.toml").read_text() == \
        (ROOT / "config/zarco.toml").read_text()
    assert (dest / "etc/udev/rules.d/99-zarco.rules").exists()
    unit = dest / "etc/systemd/system/zarco.service"
    assert "Type=notify" in unit.read_text() and "WatchdogSec=" in unit.read_text()
    wants = dest / "etc/systemd/system/multi-user.target.wants/zarco.service"
    assert wants.is_symlink()


@needs_systemd
def test_the_configuration_and_the_users_file_are_private(dest: Path) -> None:
    uid, gid = _ids(dest, "zarco")
    cfg = (dest / "etc/zarco/zarco.toml").stat()
    assert stat.S_IMODE(cfg.st_mode) == 0o640 and (cfg.st_uid, cfg.st_gid) == (0, gid)
    users = dest / "etc/zarco/shore-users"  # the vessel file's example path
    st = users.stat()
    assert stat.S_IMODE(st.st_mode) == 0o600 and (st.st_uid, st.st_gid) == (uid, gid)
    # no user in it: comments only, as the runtime reads it (user:password lines)
    from zarco_runtime.links.shore.settings import read_users

    assert read_users(str(users)) == {}


@needs_systemd
def test_the_runtime_comes_from_the_lock(dest: Path) -> None:
    """What is installed is exactly what the lock pins (and the runtime itself)."""
    pins = _pins()
    site = next((dest / "opt/zarco/lib").glob("python3*/site-packages"))
    got = {}
    for d in site.glob("*.dist-info"):
        meta = (d / "METADATA").read_text(encoding="utf-8", errors="replace")
        name = re.search(r"^Name: (.+)$", meta, re.M)
        ver = re.search(r"^Version: (.+)$", meta, re.M)
        assert name and ver
        got[_norm(name.group(1))] = ver.group(1).strip()
    got.pop("zarco-runtime")
    got.pop("pip", None)  # the venv's own, from the Python that made it
    assert got == {n: v for n, (v, _h) in pins.items() if n in got}
    missing = set(pins) - set(got)
    assert not missing, missing  # every pin applies to this Python (no markers left out)


# ------------------------------------------------------------------ the lock


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _pins() -> dict[str, tuple[str, list[str]]]:
    """name → (version, sha256 hashes) of the lock (markers for this Python only)."""
    text = LOCK.read_text()
    out: dict[str, tuple[str, list[str]]] = {}
    for block in re.split(r"\n(?=\S)", text):
        if block.startswith("#") or not block.strip():
            continue
        head = block.split("\\", 1)[0].strip()
        m = re.fullmatch(r"([A-Za-z0-9_.\-]+)==([^\s;]+)\s*(?:;\s*(.+))?", head)
        assert m is not None, head
        marker = m.group(3)
        if marker:
            from packaging.markers import Marker

            if not Marker(marker).evaluate():
                continue
        out[_norm(m.group(1))] = (m.group(2), re.findall(r"--hash=sha256:([0-9a-f]{64})",
                                                         block))
    return out


def test_the_lock_pins_every_dependency_with_hashes() -> None:
    pins = _pins()
    assert all(len(h) >= 1 for _v, h in pins.values()), pins
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    from packaging.requirements import Requirement

    wanted = [Requirement(r) for r in pyproject["project"]["dependencies"]]
    wanted += [Requirement(r) for r in pyproject["build-system"]["requires"]]
    for req in wanted:
        name = _norm(req.name)
        assert name in pins, f"{req} is not in the lock"
        assert req.specifier.contains(pins[name][0], prereleases=True), (req, pins[name])
    # the closure: every pinned distribution's own requirements are pinned too (read
    # from this .venv's metadata of the same versions, where installed)
    from importlib.metadata import PackageNotFoundError, distribution

    for name, (ver, _h) in pins.items():
        try:
            dist = distribution(name)
        except PackageNotFoundError:
            continue
        if dist.version != ver:
            continue
        for r in dist.requires or []:
            req = Requirement(r)
            if req.marker is not None and not req.marker.evaluate({"extra": ""}):
                continue
            assert _norm(req.name) in pins, f"{name} needs {req.name}, not in the lock"


def test_pip_refuses_a_file_whose_hash_is_not_the_locked_one(tmp_path: Path) -> None:
    """The lock's hashes are checked by pip: one changed, the download is refused."""
    text = LOCK.read_text()
    block = re.search(r"^pyserial==3\.5 \\\n(?:    --hash=sha256:[0-9a-f]{64}(?: \\\n)?)+", text,
                      re.M)
    assert block is not None
    bad = re.sub(r"sha256:[0-9a-f]{64}", "sha256:" + "0" * 64, block.group(0))
    req = tmp_path / "req.txt"
    req.write_text(bad.rstrip("\\\n") + "\n")
    out = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps",
                          "--require-hashes", "--dest", str(tmp_path / "dl"), "-r", str(req)],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode != 0
    assert "THESE PACKAGES DO NOT MATCH THE HASHES" in out.stderr, out.stderr[-2000:]
    good = tmp_path / "good.txt"
    good.write_text(block.group(0).rstrip("\\\n") + "\n")
    out = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps",
                          "--require-hashes", "--dest", str(tmp_path / "dl"), "-r", str(good)],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]


# ------------------------------------------------------------------ the unit


@pytest.fixture
def pty_path() -> Iterator[str]:
    m, s = os.openpty()
    try:
        yield os.ttyname(s)
    finally:
        os.close(s)
        os.close(m)


def test_device_allow_is_limited_to_the_configured_ports(tmp_path: Path, pty_path: str) -> None:
    link = tmp_path / "gps"
    link.symlink_to(pty_path)
    # a real pseudo-terminal, by its node or through a link: the pts class only
    assert classify(pty_path)[0] == ["char-pts rw"]
    assert classify(str(link))[0] == ["char-pts rw"]
    # USB adapters by class (a replug changes the minor), plugged in or not
    assert classify("/dev/ttyUSB3")[0] == ["char-ttyUSB rw"]
    assert classify("/dev/ttyACM0")[0] == ["char-ttyACM rw"]
    # a udev link whose adapter is not plugged in: both USB serial classes
    assert classify("/dev/zarco/nope")[0] == ["char-ttyUSB rw", "char-ttyACM rw"]
    # a fixed port: its node only, never the tty class (which holds the consoles)
    fixed = "/dev/ttyS0" if os.path.exists("/dev/ttyS0") else "/dev/null"
    assert classify(fixed)[0] == [f"{fixed} rw"]
    assert classify("/dev/ttyAMA7")[0] == ["/dev/ttyAMA7 rw"]
    assert serial_path("tcp://10.0.0.5:4001") == ""
    assert serial_path("serial:///dev/ttyUSB0") == "/dev/ttyUSB0"
    assert serial_path("/dev/ttyAMA0,57600") == "/dev/ttyAMA0"
    rules = allow_rules([pty_path, str(link), "/dev/ttyUSB0", "/dev/ttyUSB1", ""])
    assert rules == ["char-pts rw", "char-ttyUSB rw"]


def _write_config(path: Path, gps: str, compass: str, thrusters: str, extra: str = "") -> Path:
    path.write_text(f"""
[devices.gps]
url = "{gps}"
[devices.compass]
url = "{compass}"
[devices.thrusters]
url = "{thrusters}"
[devices.buoy]
enabled = false
url = "/dev/ttyS3"
{extra}
""")
    return path


@needs_systemd
def test_the_generated_unit_verifies_and_rates_at_most_1_5(tmp_path: Path, dest: Path,
                                                           pty_path: str) -> None:
    fixed = "/dev/ttyS0" if os.path.exists("/dev/ttyS0") else "/dev/null"
    cfg = _write_config(tmp_path / "zarco.toml", "/dev/ttyUSB0", pty_path,
                        "tcp://127.0.0.1:4001",
                        f'[mavlink]\nenabled = true\nurl = ["{fixed},57600", '
                        '"udpout:127.0.0.1:14550"]\n')
    out = subprocess.run([str(dest / "opt/zarco/bin/python"), "-m", "zarco_runtime.install",
                          "unit", "--config", str(cfg), "--template",
                          str(ROOT / "systemd/zarco.service"), "--prefix", "/opt/zarco"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    allow = re.findall(r"^DeviceAllow=(.+)$", out.stdout, re.M)
    # the GPS adapter's class, the compass pty, the MAVLink port; not the disabled
    # buoy, not the network thruster controller, no /dev/ptmx, no tty class
    assert sorted(allow) == sorted(["char-ttyUSB rw", "char-pts rw", f"{fixed} rw"])
    assert "DevicePolicy=closed" in out.stdout and "ptmx" not in "".join(allow)
    unit = tmp_path / "zarco.service"
    unit.write_text(out.stdout)
    _verify_and_rate(unit, dest)
    # the unit the install wrote (the vessel file: its udev links, not plugged in)
    installed = (dest / "etc/systemd/system/zarco.service").read_text()
    assert re.findall(r"^DeviceAllow=(.+)$", installed, re.M) == ["char-ttyACM rw",
                                                                 "char-ttyUSB rw"]
    _verify_and_rate(dest / "etc/systemd/system/zarco.service", dest)


def _verify_and_rate(unit: Path, dest: Path) -> None:
    # verify against this machine's systemd, with ExecStart where the scratch root has it
    copy = unit.parent / "verify" / "zarco.service"
    copy.parent.mkdir(exist_ok=True)
    copy.write_text(unit.read_text().replace("/opt/zarco/bin/zarco",
                                             str(dest / "opt/zarco/bin/zarco")))
    out = subprocess.run(["systemd-analyze", "verify", str(copy)], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    sec = subprocess.run(["systemd-analyze", "security", "--offline=yes", str(unit)],
                         capture_output=True, text=True, timeout=60)
    m = re.search(r"Overall exposure level for zarco.service: ([\d.]+) (\w+)", sec.stdout)
    assert m is not None, sec.stdout[-500:] + sec.stderr
    assert float(m.group(1)) <= 1.5 and m.group(2) in ("OK", "SAFE"), sec.stdout


def test_render_refuses_a_template_without_a_device_policy() -> None:
    with pytest.raises(ValueError, match="DevicePolicy=closed"):
        render_unit("[Service]\nExecStart=/opt/zarco/bin/zarco\n", [], "/opt/x", "f")


# ------------------------------------------------------------ under way or not


def test_state_from_status_and_state_file(tmp_path: Path) -> None:
    assert from_status({"mode": "idle", "armed": False}).under_way is False
    assert from_status({"mode": "idle", "armed": True}).under_way is True
    for mode in ("lines", "follow", "hold", "return", "manual"):
        st = from_status({"mode": mode, "mission": {"name": "m1"}})
        assert st.under_way is True and mode in st.text and "'m1'" in st.text
    cfg = tmp_path / "zarco.toml"
    state = tmp_path / "state.json"
    cfg.write_text(f'[supervisor]\ncontrol_socket = "{tmp_path / "none.sock"}"\n'
                   f'state_file = "{state}"\n')
    assert runtime_state(str(cfg), active=False) == State(False, "the runtime is not running")
    # running, not answering: the state file decides; without one, nobody can tell
    assert runtime_state(str(cfg), active=True).under_way is None
    mission = {"kind": "lines", "name": "north", "legs": [], "waypoints": []}
    state.write_text(json.dumps({"mission": mission, "leg": 1, "complete": False}))
    st = runtime_state(str(cfg), active=True)
    assert st.under_way is None and "'north' is not complete" in st.text
    state.write_text(json.dumps({"mission": mission, "leg": 3, "complete": True}))
    assert runtime_state(str(cfg), active=True).under_way is False


@pytest.fixture
def boat(tmp_path: Path) -> Iterator[Path]:
    """A real runtime under way: the simulated rectangle at 1×, its control socket."""
    sock = tmp_path / "control.sock"
    p = subprocess.Popen([ZARCO, "sim", str(ROOT / "config/scenarios/rectangle.toml"),
                          "--realtime", "-q", "--set", "scenario.max_duration_s=600",
                          "--set", f'runtime.supervisor.control_socket="{sock}"'],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 120.0
        while time.monotonic() < end and p.poll() is None:
            if _status(sock).get("mode") == "lines":
                break
            time.sleep(0.2)
        assert _status(sock).get("mode") == "lines", p.stderr.read() if p.stderr else ""
        yield sock
    finally:
        p.terminate()
        p.wait(timeout=60)


def _status(sock: Path) -> dict[str, object]:
    try:
        with socket.socket(socket.AF_UNIX) as s:
            s.settimeout(5.0)
            s.connect(str(sock))
            s.sendall(b'{"name": "status"}\n')
            return dict(json.loads(s.makefile().readline()))
    except (OSError, ValueError):
        return {}


def _ctl(sock: Path, name: str) -> dict[str, object]:
    out = subprocess.run([ZARCO, "ctl", "--socket", str(sock), name], capture_output=True,
                         text=True, timeout=60)
    return dict(json.loads(out.stdout))


def _tree(root: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(root)): (p.stat().st_mode, p.stat().st_size)
            for p in root.rglob("*") if not p.is_symlink()}


@needs_systemd
def test_no_upgrade_while_the_boat_is_under_way(dest: Path, boat: Path) -> None:
    """The installed configuration names a live runtime's socket: under way, the
    install changes nothing and says why (exit 3); with --wait it waits until the
    operator stops the boat, then installs; an operator's edits are kept."""
    cfg = dest / "etc/zarco/zarco.toml"
    rules = dest / "etc/udev/rules.d/99-zarco.rules"
    text = cfg.read_text().replace("lat_deg = 41.185", "lat_deg = 41.2")
    cfg.write_text(text.replace('control_socket = "/run/zarco/control.sock"',
                                f'control_socket = "{boat}"'))
    cfg.chmod(0o644)  # as an editor might leave it
    rules.write_text(rules.read_text().replace("ZARCOGPS01", "A12345"))
    before = _tree(dest)
    out = _sh("install.sh", dest)
    assert out.returncode == 3, out.stdout + out.stderr
    assert "the boat is under way (mode lines" in out.stdout
    assert "nothing changed" in out.stderr and "--force" in out.stderr
    assert _tree(dest) == before
    # --wait: it waits (asking the runtime again and again) until the boat is idle
    env = dict(os.environ, DESTDIR=str(dest))
    env.pop("VIRTUAL_ENV", None)
    p = subprocess.Popen(["bash", str(ROOT / "systemd/install.sh"), "--wait"], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout is not None
        first = p.stdout.readline()
        assert "under way" in first and "waiting until it is idle" in first, first
        assert _ctl(boat, "stop")["ok"]
        rest, err = p.communicate(timeout=900)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, first + rest + err
    assert "the runtime is idle (mode idle" in rest
    assert "lat_deg = 41.2" in cfg.read_text()
    assert (dest / "etc/zarco/zarco.toml.dist").read_text() == \
        (ROOT / "config/zarco.toml").read_text()
    assert stat.S_IMODE(cfg.stat().st_mode) == 0o640  # its mode put right, and said so
    assert f"{cfg}: now mode 640" in rest
    assert "A12345" in rules.read_text()
    assert (dest / "etc/passwd").read_text().count("zarco:x:") == 1


@needs_systemd
def test_a_configuration_the_new_runtime_refuses_stops_the_install(tmp_path: Path,
                                                                  dest: Path) -> None:
    cfg = dest / "etc/zarco/zarco.toml"
    keep = cfg.read_text()
    unit = (dest / "etc/systemd/system/zarco.service").read_text()
    try:
        cfg.write_text(keep.replace('position_lost = "idle"', 'position_lost = "hold"'))
        out = _sh("install.sh", dest)
        assert out.returncode == 2, out.stdout + out.stderr
        line = out.stderr.strip().splitlines()[-1]
        assert "failsafe.position_lost" in line and "fix it, then run the install again" \
            in line
        assert (dest / "etc/systemd/system/zarco.service").read_text() == unit
    finally:
        cfg.write_text(keep)


@needs_systemd
def test_uninstall_keeps_recordings_and_configuration(dest: Path) -> None:
    rec = dest / "var/lib/zarco/recordings/zarco-run.mcap"
    rec.write_bytes(b"\x89MCAP0\r\n")
    out = _sh("uninstall.sh", dest)
    assert out.returncode == 0, out.stdout + out.stderr
    assert not (dest / "opt/zarco").exists()
    assert not (dest / "etc/systemd/system/zarco.service").exists()
    assert not (dest / "etc/systemd/system/multi-user.target.wants/zarco.service").exists()
    assert rec.read_bytes() == b"\x89MCAP0\r\n"
    assert (dest / "etc/zarco/zarco.toml").exists()
    assert (dest / "etc/zarco/shore-users").exists()
    assert (dest / "etc/udev/rules.d/99-zarco.rules").exists()  # edited: kept
