"""Typed in-process message bus.

Publishers call :meth:`Bus.publish` (synchronous, never blocks, never awaits);
subscribers own a :class:`Subscription`, a bounded queue of one message type.
When a subscriber falls behind its queue drops the *oldest* message and
counts the drop, so a slow subscriber (a recorder, the shore link) can never
block or slow the control loop.  :class:`Latest` keeps only the newest
message of a type, for tasks that sample state at their own rate (the
controller reads the latest NavState at every tick).

Tasks talk only through the bus (LSTS DUNE's model): a driver publishes
GpsFix, the estimator publishes NavState, and so on.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable
from typing import Any, Generic, TypeVar

M = TypeVar("M")


class Subscription(Generic[M]):
    """A bounded FIFO of messages of some types (drop-oldest on overflow)."""

    def __init__(self, bus: Bus, kinds: tuple[type, ...], maxlen: int) -> None:
        self._bus = bus
        self.kinds = kinds
        self._q: deque[M] = deque()
        self._maxlen = maxlen
        self._waiter: asyncio.Future[None] | None = None
        self.dropped = 0
        self.received = 0

    def _put(self, msg: M) -> None:
        if len(self._q) >= self._maxlen:
            self._q.popleft()
            self.dropped += 1
        self._q.append(msg)
        self.received += 1
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)

    def get_nowait(self) -> M | None:
        """The oldest pending message, or None."""
        return self._q.popleft() if self._q else None

    def drain(self) -> list[M]:
        """All pending messages, oldest first."""
        out = list(self._q)
        self._q.clear()
        return out

    async def get(self) -> M:
        """Wait for the next message."""
        while not self._q:
            self._waiter = asyncio.get_running_loop().create_future()
            try:
                await self._waiter
            finally:
                self._waiter = None
        return self._q.popleft()

    def __len__(self) -> int:
        return len(self._q)

    def close(self) -> None:
        self._bus._unsubscribe(self)

    def __aiter__(self) -> Subscription[M]:
        return self

    async def __anext__(self) -> M:
        return await self.get()


class Latest(Generic[M]):
    """Holds the newest message of one type (``value`` is None until one arrives)."""

    def __init__(self, kind: type[M]) -> None:
        self.kinds = (kind,)
        self.value: M | None = None
        self.count = 0

    def _put(self, msg: M) -> None:
        self.value = msg
        self.count += 1


class _Listener:
    __slots__ = ("_put", "kinds")

    def __init__(self, kind: type, fn: Callable[[Any], None]) -> None:
        self.kinds = (kind,)
        self._put = fn


class Bus:
    """Routes messages by their exact dataclass type."""

    def __init__(self) -> None:
        self._subs: dict[type, list[Any]] = {}
        self._taps: list[Callable[[Any], None]] = []
        self.published = 0

    def subscribe(self, *kinds: type, maxlen: int = 256) -> Subscription[Any]:
        """A queue of every message whose type is one of ``kinds``, in order."""
        sub: Subscription[Any] = Subscription(self, kinds, maxlen)
        for k in kinds:
            self._subs.setdefault(k, []).append(sub)
        return sub

    def latest(self, kind: type[M]) -> Latest[M]:
        lat: Latest[M] = Latest(kind)
        self._subs.setdefault(kind, []).append(lat)
        return lat

    def listen(self, kind: type[M], fn: Callable[[M], None]) -> None:
        """Call ``fn(msg)`` synchronously, in the publisher's context, for every
        message of type ``kind``.

        For bounded-time handlers whose work must happen with no scheduling
        delay: the thruster driver putting a command on the wire, the
        navigation estimator folding a measurement in.  ``fn`` must be quick
        and must not raise (an exception is the publisher's).
        """
        self._subs.setdefault(kind, []).append(_Listener(kind, fn))

    def tap(self, fn: Callable[[Any], None]) -> None:
        """Call ``fn(msg)`` synchronously for every message (recorders, metrics).

        ``fn`` must be quick and must not raise; it is for in-process
        observers that need every message in order.
        """
        self._taps.append(fn)

    def _unsubscribe(self, sub: Any) -> None:
        for k in sub.kinds:
            lst = self._subs.get(k, [])
            if sub in lst:
                lst.remove(sub)

    def publish(self, msg: Any) -> None:
        """Deliver ``msg`` to every subscriber of its type; never blocks."""
        self.published += 1
        for s in self._subs.get(type(msg), ()):
            s._put(msg)
        for fn in self._taps:
            fn(msg)
