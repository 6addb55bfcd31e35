"""Samples read from a zenoh ring channel at a bounded pace, on their own thread.

A subscriber declared with a Python callback costs the process the
interpreter lock for every sample that arrives: a client putting a hundred
thousand heartbeats a second would make the event loop wait for the lock
all the time.  A subscriber declared with ``zenoh.handlers.RingChannel(n)``
instead keeps the latest ``n`` samples in zenoh (no Python at all, the older
ones overwritten and not counted), and a :class:`RingReader` takes at most
``batch`` of them every ``period_s`` on its own thread: whatever a client
sends, the link does at most ``batch / period_s`` pieces of work a second.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

log = logging.getLogger("zarco.shore")


class RingReader:
    """Polls one ring-channel subscriber; ``handle(sample)`` on this thread."""

    def __init__(self, name: str, period_s: float, batch: int,
                 handle: Callable[[Any], None], on_fault: Callable[[Exception], None]) -> None:
        self.name = name
        self.period_s = period_s
        self.batch = batch
        self.handle = handle
        self.on_fault = on_fault
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self, subscriber: Any) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, args=(subscriber,),
                                        name=f"zarco-shore-{self.name}", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the thread (before the session closes: the ring goes with it)."""
        self._stop.set()
        t, self._thread = self._thread, None
        if t is not None:
            t.join(timeout_s)

    def _run(self, sub: Any) -> None:
        while not self._stop.wait(self.period_s):
            for _ in range(self.batch):
                try:
                    sample = sub.try_recv()
                except Exception as exc:  # the session closing under us
                    log.debug("shore: %s: %s", self.name, exc)
                    return
                if sample is None:
                    break
                try:
                    self.handle(sample)
                except Exception as exc:  # one bad sample never ends the reader
                    self.on_fault(exc)
