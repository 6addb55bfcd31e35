"""Supervised components: one named task per device or function, restarted on failure.

LSTS DUNE's model: every task is an entity with a state, and a task that
fails is reported and restarted while the rest goes on.  A
:class:`Supervised` wrapper runs one component's ``run()``; if it raises
(or one of the bus listeners it registered through its
:class:`ComponentContext` raises), the exception is logged with its
traceback, counted, published as a :class:`ComponentState` ``failed`` (the
supervisor's ``component failed`` failsafe acts on it), the component's
listeners are removed, and after a backoff (doubling up to a cap) a fresh
instance is built and started.  Cancellation is never caught: on shutdown
every component is cancelled and awaited.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import traceback
from collections.abc import Awaitable, Callable
from typing import Protocol, TypeVar

from zarco_core.bus import Bus, Message
from zarco_core.clock import Clock
from zarco_core.messages import ComponentState

M = TypeVar("M", bound=Message)

#: restart backoff bounds (s)
BACKOFF_MIN_S = 0.1
BACKOFF_MAX_S = 5.0
#: a component that ran this long without failing starts again at the minimum backoff
STABLE_S = 30.0


class Runnable(Protocol):
    def run(self) -> Awaitable[None]: ...


class ComponentContext:
    """What a component instance gets: its name, the bus and clock, and
    :meth:`listen`, which registers bus listeners whose exceptions are this
    component's failure (not the publisher's)."""

    def __init__(self, name: str, bus: Bus, clock: Clock) -> None:
        self.name = name
        self.bus = bus
        self.clock = clock
        self._failure: asyncio.Future[None] | None = None
        self.error: BaseException | None = None
        self.failed_on: object = None

    def listen(self, kind: type[M], fn: Callable[[M], None]) -> None:
        self.bus.listen(kind, fn, owner=self)

    def listener_failed(self, exc: BaseException, msg: object) -> None:
        if self.error is None:
            self.error = exc
            self.failed_on = msg
            f = self._failure
            if f is not None and not f.done():
                f.set_exception(exc)

    def close(self) -> None:
        self.bus.remove_owner(self)

    async def run(self, coro: Awaitable[None]) -> None:
        """Run ``coro`` until it ends, raises, or a listener of ours raises."""
        loop = asyncio.get_running_loop()
        self._failure = loop.create_future()
        if self.error is not None:  # failed while being built
            raise self.error
        task = asyncio.ensure_future(coro)
        try:
            done, _ = await asyncio.wait({task, self._failure},
                                         return_when=asyncio.FIRST_COMPLETED)
            if self._failure in done:
                self._failure.result()  # raises the listener's exception
            task.result()
        finally:
            if not task.done():
                task.cancel()
                with contextlib.suppress(Exception, asyncio.CancelledError):
                    await task
            if not self._failure.done():
                self._failure.cancel()


Factory = Callable[[ComponentContext], Runnable]


class Supervised:
    """Runs one component, restarting it with backoff whenever it fails."""

    def __init__(self, name: str, factory: Factory, bus: Bus, clock: Clock,
                 backoff_min_s: float = BACKOFF_MIN_S,
                 backoff_max_s: float = BACKOFF_MAX_S) -> None:
        self.name = name
        self.factory = factory
        self.bus = bus
        self.clock = clock
        self.backoff_min_s = backoff_min_s
        self.backoff_max_s = backoff_max_s
        self.restarts = 0
        self.failures = 0
        self.state = "starting"
        self.last_error = ""
        self.instance: Runnable | None = None
        self.log = logging.getLogger(f"zarco.{name}")

    def _publish(self, state: str) -> None:
        self.state = state
        self.bus.publish(ComponentState(self.clock.now(), self.name, state, self.restarts,
                                        self.failures, self.last_error))

    async def run(self) -> None:
        backoff = self.backoff_min_s
        while True:
            ctx = ComponentContext(self.name, self.bus, self.clock)
            started = self.clock.now()
            try:
                self.instance = self.factory(ctx)
                self._publish("running")
                await ctx.run(self.instance.run())
                # a component's run() is meant to last: returning is a failure too
                raise RuntimeError(f"{self.name} stopped by itself")
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self.failures += 1
                self.last_error = f"{type(exc).__name__}: {exc}"
                where = (f" on {type(ctx.failed_on).__name__}"
                         if ctx.failed_on is not None else "")
                self.log.error("%s failed%s (failure %d), restarting in %.2f s:\n%s",
                               self.name, where, self.failures, backoff,
                               "".join(traceback.format_exception(exc)).rstrip())
                self._publish("failed")
            finally:
                ctx.close()
            if self.clock.now() - started > STABLE_S:
                backoff = self.backoff_min_s
            await asyncio.sleep(backoff)
            backoff = min(self.backoff_max_s, backoff * 2.0)
            self.restarts += 1
            self._publish("restarting")
