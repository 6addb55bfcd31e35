"""The vessel-computer install (systemd/install.sh) into a scratch root: the tree it
makes, that it is idempotent and keeps an operator's edits, that the installed unit
passes ``systemd-analyze verify`` and rates "OK" in ``systemd-analyze security``,
and that uninstall keeps the recordings and the configuration."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(shutil.which("systemd-analyze") is None,
                                reason="systemd-analyze not installed (.ci/run installs it)")


def _sh(script: str, dest: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, DESTDIR=str(dest))
    env.pop("VIRTUAL_ENV", None)
    return subprocess.run(["bash", str(ROOT / "systemd" / script)], env=env,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def dest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("root")
    out = _sh("install.sh", d)
    assert out.returncode == 0, out.stdout + out.stderr
    return d


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


def test_the_installed_unit_verifies_and_is_hardened(dest: Path, tmp_path: Path) -> None:
    unit = dest / "etc/systemd/system/zarco.service"
    # verify against this machine's systemd, with ExecStart where the scratch root has it
    copy = tmp_path / "zarco.service"
    copy.write_text(unit.read_text().replace("/opt/zarco/bin/zarco",
                                             str(dest / "opt/zarco/bin/zarco")))
    out = subprocess.run(["systemd-analyze", "verify", str(copy)], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    sec = subprocess.run(["systemd-analyze", "security", "--offline=yes", str(unit)],
                         capture_output=True, text=True, timeout=60)
    m = re.search(r"Overall exposure level for zarco.service: ([\d.]+) (\w+)", sec.stdout)
    assert m is not None, sec.stdout[-500:] + sec.stderr
    assert float(m.group(1)) <= 2.5 and m.group(2) in ("OK", "SAFE")


def test_install_again_keeps_an_operators_edits(dest: Path) -> None:
    cfg = dest / "etc/zarco/zarco.toml"
    rules = dest / "etc/udev/rules.d/99-zarco.rules"
    cfg.write_text(cfg.read_text().replace("lat_deg = 41.185", "lat_deg = 41.2"))
    rules.write_text(rules.read_text().replace("ZARCOGPS01", "A12345"))
    out = _sh("install.sh", dest)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "lat_deg = 41.2" in cfg.read_text()
    assert (dest / "etc/zarco/zarco.toml.dist").read_text() == \
        (ROOT / "config/zarco.toml").read_text()
    assert "A12345" in rules.read_text()
    assert (dest / "etc/passwd").read_text().count("zarco:x:") == 1


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
    assert (dest / "etc/udev/rules.d/99-zarco.rules").exists()  # edited: kept
