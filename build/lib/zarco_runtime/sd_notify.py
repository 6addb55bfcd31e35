"""systemd's notify protocol (``sd_notify(3)``): readiness, watchdog, status.

Under ``Type=notify`` systemd gives the service ``NOTIFY_SOCKET`` (a unix
datagram socket; a leading ``@`` is the abstract namespace) and, with
``WatchdogSec=``, ``WATCHDOG_USEC``.  The runtime sends, as single datagrams:

``READY=1``       once every enabled device has been opened and the supervisor runs
``WATCHDOG=1``    every half watchdog period, *only* while the control loop has
                  ticked since the last ping and the supervisor is running and has
                  evaluated its failsafes recently: a stalled control loop or a
                  dead supervisor stops the pings, and systemd kills and restarts
                  the service (which boots idle)
``STATUS=...``    the mode and active failsafes, at each change
``STOPPING=1``    on shutdown

Written here rather than taken from a library: the protocol is one
``sendto`` of a short text, and the python-systemd binding needs libsystemd
headers to build.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import socket
from collections.abc import Callable

from zarco_core.messages import HealthState, VesselStatus

log = logging.getLogger("zarco.notify")


def notify_address(value: str) -> str | bytes:
    """The socket address of ``NOTIFY_SOCKET`` (abstract namespace for ``@...``)."""
    return b"\0" + value[1:].encode() if value.startswith("@") else value


class Notifier:
    """Sends the notify datagrams; see the module docstring."""

    def __init__(self, socket_path: str, watchdog_usec: int | None,
                 ticks: Callable[[], int], supervisor_ok: Callable[[], bool],
                 devices_open: Callable[[], bool], ready_timeout_s: float = 10.0) -> None:
        self.address = notify_address(socket_path)
        self.period_s = (watchdog_usec / 1e6) / 2.0 if watchdog_usec else None
        self.ticks = ticks
        self.supervisor_ok = supervisor_ok
        self.devices_open = devices_open
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.ready_timeout_s = ready_timeout_s
        self.ready = False
        self.pings = 0
        self.withheld = 0
        self._status = ""

    def send(self, text: str) -> None:
        try:
            self.sock.sendto(text.encode(), self.address)
        except OSError as exc:  # systemd gone: nothing to tell
            log.debug("notify: %s", exc)

    def on_status(self, st: VesselStatus) -> None:
        text = f"STATUS=mode {st.mode}" + (f"; failsafes: {', '.join(st.failsafes)}"
                                           if st.failsafes else "")
        if text != self._status:
            self._status = text
            self.send(text)

    async def run(self) -> None:
        last_ticks = self.ticks()
        period = self.period_s or 0.25
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        try:
            while True:
                await asyncio.sleep(min(period, 0.25) if not self.ready else period)
                if not self.ready and self.supervisor_ok():
                    waited = loop.time() - t0
                    if self.devices_open() or waited > self.ready_timeout_s:
                        # a device still missing after the timeout: ready anyway (the
                        # runtime keeps the thrusters at zero and reports it)
                        self.ready = True
                        self.send("READY=1")
                        log.info("ready%s", "" if self.devices_open()
                                 else f" (a device still missing after {waited:.0f} s)")
                if self.period_s is None or not self.ready:
                    continue
                n = self.ticks()
                if n > last_ticks and self.supervisor_ok():
                    self.send("WATCHDOG=1")
                    self.pings += 1
                else:
                    self.withheld += 1
                    log.error("watchdog ping withheld: %s",
                              "control loop stalled" if n <= last_ticks
                              else "supervisor not running")
                last_ticks = n
        finally:
            self.send("STOPPING=1")
            with contextlib.suppress(OSError):
                self.sock.close()


def from_environment() -> tuple[str, int | None] | None:
    """(NOTIFY_SOCKET, WATCHDOG_USEC) when run by systemd under Type=notify."""
    path = os.environ.get("NOTIFY_SOCKET")
    if not path:
        return None
    usec = os.environ.get("WATCHDOG_USEC")
    pid = os.environ.get("WATCHDOG_PID")
    if pid and pid != str(os.getpid()):
        usec = None  # the watchdog is meant for another process
    return path, int(usec) if usec and usec.isdigit() else None


def devices_opened(states: Callable[[], list[HealthState]]) -> Callable[[], bool]:
    """True once no enabled device is still waiting for its first open."""
    return lambda: all(s is not HealthState.DISCONNECTED for s in states())
