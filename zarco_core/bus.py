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

A listener that raises never reaches its publisher: the bus catches the
exception and hands it to the listener's *owner* (the supervised component
that registered it, :mod:`zarco_core.component`), which stops all its
listeners and is restarted; a listener without an owner is logged and
counted (``listener_errors``).

Types: a message is any object with a ``t`` (:class:`Message`); messages are
routed by their exact class, so ``bus.latest(NavState)`` is a
``Latest[NavState]``, ``bus.subscribe(A, B)`` a ``Subscription[A | B]`` and a
listener registered for ``Heading`` is called with a ``Heading``.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Callable
from typing import Any, Generic, Protocol, TypeVar, overload

log = logging.getLogger("zarco.bus")


class Message(Protocol):
    """What the bus carries: an object (a dataclass, in practice) whose ``t`` is
    the runtime clock time (s) at which it became valid.  The bus itself reads
    nothing but the message's class."""

    @property
    def t(self) -> float: ...


M = TypeVar("M", bound=Message)
M2 = TypeVar("M2", bound=Message)


class Listen(Protocol):
    """``listen(kind, fn)``: how a component registers a bus listener (its own
    :meth:`ComponentContext.listen <zarco_core.component.ComponentContext.listen>`,
    so that a failure is its own, or plain :meth:`Bus.listen`)."""

    def __call__(self, kind: type[M], fn: Callable[[M], None], /) -> None: ...


class ListenerOwner(Protocol):
    """Who is responsible for a listener: told when one of its listeners raised."""

    def listener_failed(self, exc: BaseException, msg: object) -> None: ...


class _Sink(Protocol):
    """What the bus delivers to: a subscription, a latest-value holder or a
    listener, for the message classes in ``kinds``.

    ``_put`` takes ``Any`` on purpose: the bus keeps its sinks in one table keyed
    by message class and gives each sink only messages of its own ``kinds``
    (exact class match), a pairing the type system cannot state; each sink's
    own ``_put`` is precisely typed."""

    @property
    def kinds(self) -> tuple[type, ...]: ...

    def _put(self, msg: Any, /) -> None: ...


class Subscription(Generic[M]):
    """A bounded FIFO of messages of some types (drop-oldest on overflow)."""

    def __init__(self, bus: Bus, kinds: tuple[type[M], ...], maxlen: int) -> None:
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


class _Listener(Generic[M]):
    __slots__ = ("_put", "kinds", "owner")

    def __init__(self, kind: type[M], fn: Callable[[M], None],
                 owner: ListenerOwner | None = None) -> None:
        self.kinds: tuple[type[M]] = (kind,)
        self._put = fn
        self.owner = owner


class Bus:
    """Routes messages by their exact dataclass type."""

    def __init__(self) -> None:
        self._subs: dict[type, list[_Sink]] = {}
        self._taps: list[Callable[[Message], None]] = []
        self.published = 0
        self.listener_errors = 0

    @overload
    def subscribe(self, kind: type[M], /, *, maxlen: int = 256) -> Subscription[M]: ...

    @overload
    def subscribe(self, kind: type[M], kind2: type[M2], /, *,
                  maxlen: int = 256) -> Subscription[M | M2]: ...

    @overload
    def subscribe(self, kind: type[Message], kind2: type[Message], kind3: type[Message], /,
                  *kinds: type[Message], maxlen: int = 256) -> Subscription[Message]: ...

    def subscribe(self, *kinds: type[Message], maxlen: int = 256) -> Subscription[Any]:
        """A queue of every message whose type is one of ``kinds``, in order.

        Typed by the overloads above: one or two kinds give a subscription of
        exactly those classes, more a subscription of any :class:`Message`."""
        sub: Subscription[Message] = Subscription(self, kinds, maxlen)
        for k in kinds:
            self._subs.setdefault(k, []).append(sub)
        return sub

    def latest(self, kind: type[M]) -> Latest[M]:
        lat: Latest[M] = Latest(kind)
        self._subs.setdefault(kind, []).append(lat)
        return lat

    def listen(self, kind: type[M], fn: Callable[[M], None],
               owner: ListenerOwner | None = None) -> None:
        """Call ``fn(msg)`` synchronously, in the publisher's context, for every
        message of type ``kind``.

        For bounded-time handlers whose work must happen with no scheduling
        delay: the thruster driver putting a command on the wire, the
        navigation estimator folding a measurement in.  ``fn`` must be quick
        and should not raise: an exception goes to ``owner`` (which stops and
        restarts its component), or is logged and counted, never to the
        publisher.
        """
        self._subs.setdefault(kind, []).append(_Listener(kind, fn, owner))

    def remove_owner(self, owner: ListenerOwner) -> None:
        """Remove every listener registered by ``owner``."""
        # new lists: a publish() iterating the old one is not disturbed
        for k, lst in list(self._subs.items()):
            self._subs[k] = [s for s in lst
                             if not (isinstance(s, _Listener) and s.owner is owner)]

    def tap(self, fn: Callable[[Message], None]) -> None:
        """Call ``fn(msg)`` synchronously for every message (recorders, metrics).

        ``fn`` must be quick and must not raise; it is for in-process
        observers that need every message in order.
        """
        self._taps.append(fn)

    def _unsubscribe(self, sub: _Sink) -> None:
        for k in sub.kinds:
            lst = self._subs.get(k, [])
            if sub in lst:
                lst.remove(sub)

    def publish(self, msg: Message) -> None:
        """Deliver ``msg`` to every subscriber of its type; never blocks, never
        raises (a failing listener is its owner's problem)."""
        self.published += 1
        for s in self._subs.get(type(msg), ()):
            try:
                s._put(msg)
            except Exception as exc:
                self._failed(s, msg, exc)
        for fn in self._taps:
            try:
                fn(msg)
            except Exception as exc:
                self._failed(None, msg, exc)

    def _failed(self, sub: _Sink | None, msg: object, exc: Exception) -> None:
        self.listener_errors += 1
        owner = getattr(sub, "owner", None)
        if owner is not None:
            self.remove_owner(owner)
            owner.listener_failed(exc, msg)
            return
        if self.listener_errors <= 10 or self.listener_errors % 1000 == 0:
            log.error("a bus listener raised on %s (%d so far)", type(msg).__name__,
                      self.listener_errors, exc_info=exc)
