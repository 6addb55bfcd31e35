"""Helpers for the web map's tests and benchmark: ``zarco shore web`` in its own
process with a console configuration file (as an operator runs it), and the
distribution's Chromium driven by Playwright."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from shore_support import ROOT

#: the distribution's browser (Debian's chromium package; never `playwright install`)
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu",
                 "--disable-background-networking", "--disable-component-update",
                 "--no-first-run"]


def launch(playwright: Any) -> Any:
    """The headless browser."""
    return playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)


def console_config(path: Path, endpoints: list[tuple[str, Path]], vessel: str = "") -> Path:
    """A console configuration: the endpoints and their credentials files (one
    ``credentials_file`` for all when they share it, else ``[[endpoints]]``
    tables)."""
    lines = [f'vessel = "{vessel}"\n'] if vessel else []
    creds = {c for _, c in endpoints}
    if len(creds) == 1:
        eps = ", ".join(f'"{ep}"' for ep, _ in endpoints)
        lines.append(f'connect = [{eps}]\ncredentials_file = "{creds.pop()}"\n')
    else:
        for ep, cred in endpoints:
            lines.append(f'[[endpoints]]\nendpoint = "{ep}"\ncredentials_file = "{cred}"\n')
    path.write_text("\n".join(lines))
    path.chmod(0o600)
    return path


class WebProcess:
    """``zarco shore web --listen 127.0.0.1:PORT`` with the console configuration
    ``config`` (in the environment, as the console reads it)."""

    def __init__(self, config: Path, port: int, log: Path | None = None,
                 extra: list[str] | None = None) -> None:
        self.port = port
        self.args = [sys.executable, "-m", "zarco_runtime.cli", "shore", "web",
                     "--listen", f"127.0.0.1:{port}", *(extra or [])]
        self.env = {**os.environ, "ZARCO_SHORE_CONFIG": str(config), "PYTHONUNBUFFERED": "1"}
        for k in ("ZARCO_SHORE_CONNECT", "ZARCO_SHORE_CREDENTIALS", "ZARCO_SHORE_PASSWORD"):
            self.env.pop(k, None)
        self.log = log
        self.proc: subprocess.Popen[str] | None = None
        self.url = ""
        self.lines: queue.Queue[str] = queue.Queue()

    def start(self, timeout_s: float = 30.0) -> WebProcess:
        self.proc = subprocess.Popen(self.args, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                                     env=self.env)
        threading.Thread(target=self._read, daemon=True).start()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.5)
            except queue.Empty:
                if self.proc.poll() is not None:
                    break
                continue
            if line.startswith("zarco shore web: http://"):
                self.url = line.split()[3]
                return self
        self.stop()
        raise AssertionError(f"zarco shore web did not start: {self.output()}")

    def _read(self) -> None:
        assert self.proc is not None and self.proc.stdout is not None
        out = self.log.open("w") if self.log is not None else None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))
            if out is not None:
                out.write(line)
                out.flush()
        if out is not None:
            out.close()

    def output(self) -> str:
        got = []
        while not self.lines.empty():
            got.append(self.lines.get_nowait())
        return "\n".join(got)

    def stop(self, timeout_s: float = 10.0) -> int:
        p = self.proc
        if p is None:
            return 0
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout_s)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        return int(p.returncode)

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid
