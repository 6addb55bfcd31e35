"""Clocks: monotonic time on the boat, virtual time in simulation.

Every task reads time through a :class:`Clock` and sleeps with
``await clock.sleep_until(t)``.  Both clocks are backed by the asyncio event
loop's own time, so ordinary ``asyncio.sleep`` / ``wait_for`` timeouts agree
with them:

* on the boat and in HIL the loop is a normal one and its time is
  ``time.monotonic()``;
* in simulation the loop is a :class:`VirtualTimeEventLoop`, whose time only
  moves when every task is waiting: when the selector would block for
  ``timeout`` seconds, the loop polls without blocking and, if nothing is
  ready, jumps straight to the next timer.  The very same tasks then run
  faster than real time, deterministically (the idea of the ``looptime``
  pytest plugin, done here without patching).

``Clock.utc()`` maps runtime time to UTC seconds since the epoch; on the boat
that is the system clock (GPS-disciplined by chrony), in simulation the
scenario's start time plus the virtual time.
"""

from __future__ import annotations

import asyncio
import selectors
import time
from collections.abc import Coroutine
from typing import Any, TypeVar

T = TypeVar("T")


class Clock:
    """Runtime time in seconds, backed by the running event loop."""

    def __init__(self, utc_offset_s: float | None = None) -> None:
        self._utc_offset_s = utc_offset_s
        self._loop: asyncio.AbstractEventLoop | None = None
        self._time = time.monotonic

    def now(self) -> float:
        """Runtime time (s): ``loop.time()``; monotonic, or virtual in simulation."""
        loop = asyncio.get_running_loop()
        if loop is not self._loop:
            self._loop, self._time = loop, loop.time
        return self._time()

    def utc(self, t: float | None = None) -> float:
        """UTC seconds since 1970 at runtime time ``t`` (default: now)."""
        tt = self.now() if t is None else t
        if self._utc_offset_s is None:
            return time.time() - (self.now() - tt)
        return self._utc_offset_s + tt

    async def sleep_until(self, t: float) -> None:
        """Sleep until runtime time ``t`` (returns at once if it has passed)."""
        loop = asyncio.get_running_loop()
        delay = t - loop.time()
        if delay > 0:
            await asyncio.sleep(delay)
        else:
            await asyncio.sleep(0)

    async def sleep(self, dt: float) -> None:
        await asyncio.sleep(dt)


class DeadlockError(RuntimeError):
    """The virtual loop has nothing scheduled and nothing can wake it."""


class _VirtualSelector(selectors.BaseSelector):
    """Wraps a real selector: never blocks; advances the loop's virtual time."""

    def __init__(self, inner: selectors.BaseSelector, loop: VirtualTimeEventLoop) -> None:
        self._inner = inner
        self._loop = loop

    def register(self, fileobj, events, data=None):  # type: ignore[no-untyped-def]
        return self._inner.register(fileobj, events, data)

    def unregister(self, fileobj):  # type: ignore[no-untyped-def]
        return self._inner.unregister(fileobj)

    def modify(self, fileobj, events, data=None):  # type: ignore[no-untyped-def]
        return self._inner.modify(fileobj, events, data)

    def get_map(self):  # type: ignore[no-untyped-def]
        return self._inner.get_map()

    def close(self) -> None:
        self._inner.close()

    def select(self, timeout: float | None = None):  # type: ignore[no-untyped-def]
        events = self._inner.select(0)
        if events or timeout == 0:
            return events
        self._loop._advance(timeout)
        return events


class VirtualTimeEventLoop(asyncio.SelectorEventLoop):
    """An asyncio loop whose clock jumps to the next timer when all tasks wait.

    Real file descriptors still work (they are polled without blocking), so
    the loop's own self-pipe and ``call_soon_threadsafe`` keep working; but
    waiting for a *real* device would spin virtual time forward, so the
    simulation uses in-memory transports only.
    """

    def __init__(self, start: float = 0.0) -> None:
        super().__init__()
        self._vt = float(start)
        self._selector = _VirtualSelector(self._selector, self)  # type: ignore[has-type]
        self.idle_spins = 0

    def time(self) -> float:
        return self._vt

    def _advance(self, timeout: float | None) -> None:
        scheduled = self._scheduled  # type: ignore[attr-defined]
        self.idle_spins = 0 if scheduled or timeout is not None else self.idle_spins
        if scheduled:
            when = scheduled[0]._when
            if when > self._vt:
                self._vt = when
            return
        if timeout is None:
            self.idle_spins += 1
            if self.idle_spins > 1000:
                raise DeadlockError("virtual clock: no timers and no ready tasks")
            return
        self._vt += timeout


def run_virtual(coro: Coroutine[Any, Any, T], start: float = 0.0) -> T:
    """Run ``coro`` to completion on a fresh :class:`VirtualTimeEventLoop`."""
    loop = VirtualTimeEventLoop(start)
    try:
        asyncio.set_event_loop(loop)
        return loop.run_until_complete(coro)
    finally:
        try:
            loop.run_until_complete(loop.shutdown_asyncgens())
        finally:
            asyncio.set_event_loop(None)
            loop.close()
