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
import heapq
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


#: the asyncio loop's threshold for purging cancelled timers in bulk (as in CPython)
_MIN_SCHEDULED_TIMER_HANDLES = 100
_MIN_CANCELLED_TIMER_HANDLES_FRACTION = 0.5
#: a busy virtual loop (always something ready) still polls real descriptors this often
_POLL_EVERY = 64


class VirtualTimeEventLoop(asyncio.SelectorEventLoop):
    """An asyncio loop whose clock jumps to the next timer when all tasks wait.

    Real file descriptors still work (they are polled without blocking), so
    the loop's own self-pipe and ``call_soon_threadsafe`` keep working; but
    waiting for a *real* device would spin virtual time forward, so the
    simulation uses in-memory transports only.

    One iteration (:meth:`_run_once`) is asyncio's own, less what a virtual
    clock does not need: real descriptors are polled only when every task
    waits (before the clock jumps; no time passes meanwhile, so nothing is
    late) and every ``_POLL_EVERY`` iterations of a loop that never waits,
    instead of with a system call at every iteration.  In debug mode the
    standard iteration runs.
    """

    def __init__(self, start: float = 0.0) -> None:
        super().__init__()
        self._vt = float(start)
        self._selector = _VirtualSelector(self._selector, self)  # type: ignore[has-type]
        self.idle_spins = 0
        self._busy = 0

    def time(self) -> float:
        return self._vt

    def _run_once(self) -> None:
        lp: Any = self  # asyncio's private loop state (CPython 3.11's BaseEventLoop)
        if lp._debug:
            super()._run_once()  # type: ignore[misc]
            return
        ready = lp._ready
        sched = lp._scheduled
        n_sched = len(sched)
        if (n_sched > _MIN_SCHEDULED_TIMER_HANDLES
                and lp._timer_cancelled_count / n_sched > _MIN_CANCELLED_TIMER_HANDLES_FRACTION):
            keep = []
            for h in sched:
                if h._cancelled:
                    h._scheduled = False
                else:
                    keep.append(h)
            heapq.heapify(keep)
            lp._scheduled = sched = keep
            lp._timer_cancelled_count = 0
        else:
            while sched and sched[0]._cancelled:
                lp._timer_cancelled_count -= 1
                heapq.heappop(sched)._scheduled = False
        if ready or lp._stopping:
            self._busy += 1
            if self._busy >= _POLL_EVERY:
                self._busy = 0
                lp._process_events(lp._selector.select(0))
        else:
            self._busy = 0
            # every task waits: real descriptors first, else the clock jumps
            lp._process_events(lp._selector.select(1.0 if sched else None))
        end = self._vt + lp._clock_resolution
        pop = heapq.heappop
        while sched and sched[0]._when < end:
            h = pop(sched)
            h._scheduled = False
            ready.append(h)
        popleft = ready.popleft
        for _ in range(len(ready)):
            h = popleft()
            if not h._cancelled:
                h._run()

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
