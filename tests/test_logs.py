"""Under systemd (stderr is the journal: JOURNAL_STREAM), ``zarco run`` logs with
sd-daemon priority prefixes, at INFO, without timestamps; on a terminal it does not."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time
import tty
from pathlib import Path

from zarco_runtime.logs import JournalFormatter

BIN = Path(sys.executable).with_name("zarco")


def test_priorities_map_like_syslog() -> None:
    f = JournalFormatter()
    rec = logging.LogRecord("zarco.x", logging.ERROR, __file__, 1, "two\nlines", None, None)
    assert f.format(rec) == "<3>zarco.x: two\n<3>lines"
    rec.levelno = logging.WARNING
    assert f.format(rec).startswith("<4>")


def test_zarco_run_under_the_journal_prefixes_priorities(tmp_path: Path) -> None:
    fds, paths = [], []
    for _ in range(3):
        m, s = os.openpty()
        tty.setraw(s)
        paths.append(os.ttyname(s))
        os.close(s)
        fds.append(m)
    cfg = tmp_path / "zarco.toml"
    cfg.write_text("".join(f'[devices.{n}]\nurl = "{p}"\n'
                           for n, p in zip(("gps", "compass", "thrusters"), paths, strict=True)))
    log = tmp_path / "journal"
    with log.open("w") as err:
        st = os.fstat(err.fileno())
        env = dict(os.environ, JOURNAL_STREAM=f"{st.st_dev}:{st.st_ino}")
        p = subprocess.Popen([str(BIN), "run", "--config", str(cfg)], stderr=err, env=env)
        end = time.monotonic() + 30.0  # until it has started (slow on a loaded machine)
        while "supervisor started" not in log.read_text() and time.monotonic() < end:
            time.sleep(0.1)
        p.send_signal(signal.SIGTERM)
        assert p.wait(timeout=20) == 0
    for fd in fds:
        os.close(fd)
    lines = log.read_text().splitlines()
    assert lines and all(ln[:3] in ("<2>", "<3>", "<4>", "<6>", "<7>") for ln in lines), lines
    assert any(ln.startswith("<6>zarco.supervisor: mode: supervisor started") for ln in lines)
    assert any(ln.startswith("<4>zarco: stopping: SIGTERM") for ln in lines)
