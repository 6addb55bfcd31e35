"""``zarco hil`` ends its ``zarco run`` on SIGTERM, SIGINT and SIGHUP, with real
signals sent to the real command: the runtime is stopped as at the end of a run
(zero thrust last on the wire), the report is written, and no runtime is left
holding the pseudo-terminals.  Even a SIGKILL of the rig, which it cannot
handle, ends its runtime (the kernel's parent-death signal)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from procs import alive, children

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "hil" / "scenarios" / "line_faults.toml"
ZARCO = str(Path(sys.executable).with_name("zarco"))
#: generous: a loaded 2-core machine starts a runtime in a few seconds
START_TIMEOUT_S = 90.0


@pytest.fixture(autouse=True)
def _needs_ptys() -> None:
    try:
        a, b = os.openpty()
    except OSError as exc:  # pragma: no cover - a container without /dev/pts
        pytest.skip(f"no pseudo-terminals here: {exc}")
    os.close(a)
    os.close(b)


def runtime_of(rig: subprocess.Popen[str]) -> int:
    """The pid of the rig's ``zarco run`` (its only child running ``run --config``)."""
    for pid in children(rig.pid):
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"run" in argv and b"--config" in argv:
            return pid
    return 0


def start_rig(tmp_path: Path) -> tuple[subprocess.Popen[str], Path]:
    run_dir = tmp_path / "run"
    rig = subprocess.Popen(
        [ZARCO, "hil", str(SCENARIO), "--no-faults", "--run-dir", str(run_dir),
         "--report", str(tmp_path / "report.json"), "-q"],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return rig, run_dir


def wait_running(rig: subprocess.Popen[str], run_dir: Path) -> int:
    """Wait until the runtime steers the mission (its status file says so);
    return its pid."""
    end = time.monotonic() + START_TIMEOUT_S
    status = run_dir / "status.jsonl"
    pid = 0
    while time.monotonic() < end and rig.poll() is None:
        pid = pid or runtime_of(rig)
        if pid and status.exists() and '"mode": "lines"' in status.read_text():
            return pid
        time.sleep(0.1)
    rig.kill()
    out, err = rig.communicate()
    pytest.fail(f"the HIL run never started: {out[-2000:]}{err[-2000:]}")


def finish(rig: subprocess.Popen[str], timeout: float = 60.0) -> tuple[str, str]:
    try:
        return rig.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        rig.kill()
        out, err = rig.communicate()
        pytest.fail(f"zarco hil did not end after the signal: {out[-2000:]}{err[-2000:]}")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_a_signal_stops_the_runtime_and_writes_the_report(sig: signal.Signals,
                                                          tmp_path: Path) -> None:
    rig, run_dir = start_rig(tmp_path)
    pid = wait_running(rig, run_dir)
    assert alive(pid)
    rig.send_signal(sig)
    out, err = finish(rig)
    assert rig.returncode == 0, out[-2000:] + err[-2000:]
    assert not alive(pid), f"the runtime {pid} outlived zarco hil"
    report: dict[str, Any] = json.loads((tmp_path / "report.json").read_text())
    h = report["hil"]
    assert report["stop"] == f"signal {sig.name}"
    assert h["runtime"]["exit_code"] == 0 and not h["runtime"]["exited_before_the_end"]
    assert h["zero_thrust_on_exit"], h["last_command"]
    assert h["runtime"]["status_final"]  # the runtime wrote its last words
    assert err.count(f"zarco hil: {sig.name}: stopping the runtime") == 1, err[-2000:]
    assert f"signal {sig.name}" in out and "Traceback" not in out + err


def test_killing_the_rig_ends_its_runtime(tmp_path: Path) -> None:
    """SIGKILL cannot be handled: the runtime gets SIGTERM from the kernel when
    its parent dies, and stops."""
    rig, run_dir = start_rig(tmp_path)
    pid = wait_running(rig, run_dir)
    rig.kill()
    finish(rig)
    end = time.monotonic() + 30.0
    while alive(pid) and time.monotonic() < end:
        time.sleep(0.1)
    assert not alive(pid), f"the runtime {pid} outlived its killed rig"
