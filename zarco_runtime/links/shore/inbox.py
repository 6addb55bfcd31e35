"""From zenoh's threads to the event loop: bounded queues, drained in slices.

zenoh calls the shore link's callbacks on its own threads; they only post
here.  The event loop drains what was posted in slices of at most
:data:`SLICE_ITEMS` items or :data:`SLICE_S` seconds, then yields (the rest
waits for the next loop iteration), so that a burst of thousands of commands
never holds the control loop for more than a few milliseconds at a time.

Each kind has its own bound, so a flood of one never crowds out another:

* commands: a FIFO of :data:`COMMANDS_MAX` queries; one more is refused at
  once ("busy") by the poster.  ``stop`` has a FIFO of its own
  (:data:`STOPS_MAX`), handled before anything else: a flood of other
  commands never delays or refuses a stop;
* operator heartbeats: only the latest per user is kept (what the
  link-lost failsafe needs is that one was heard), for at most
  :data:`USERS_MAX` users at a time; the others are counted and dropped;
* RTCM: a FIFO of :data:`RTCM_MAX` chunks of whole frames; beyond, the chunk
  is counted and dropped.

Every item is handled in isolation: an exception from handling one item is
given to ``on_fault`` with the item, and the next item is handled as if
nothing happened.
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: queries waiting for the event loop; one more is answered "busy" at once
COMMANDS_MAX = 1024
#: stop queries waiting (ahead of everything else)
STOPS_MAX = 64
#: heartbeats waiting (the latest of each user)
USERS_MAX = 16
#: RTCM chunks waiting
RTCM_MAX = 64
#: a drain handles at most this many items, and stops after this long (s)
SLICE_ITEMS = 64
SLICE_S = 0.002


@dataclass(slots=True)
class Query:
    """A ``cmd/<name>`` query as read on zenoh's thread (a payload or attachment
    larger than its bound is not copied: empty, with its ``size``)."""

    query: Any
    key: str
    payload: bytes
    size: int
    attachment: bytes
    att_size: int


@dataclass(slots=True)
class Heartbeat:
    """An operator heartbeat decoded on zenoh's thread (``user`` as given)."""

    user: str


@dataclass(slots=True)
class Corrections:
    """Whole, CRC-valid RTCM3 frames (concatenated) for the GPS receiver."""

    data: bytes


Item = Query | Heartbeat | Corrections


class Inbox:
    """Bounded per-kind queues between zenoh's threads and the event loop."""

    def __init__(self, loop: asyncio.AbstractEventLoop, handle: Callable[[Item], None],
                 on_fault: Callable[[Item, Exception], None]) -> None:
        self.loop = loop
        self.handle = handle
        self.on_fault = on_fault
        self._lock = threading.Lock()
        self._commands: deque[Query] = deque()
        self._stops: deque[Query] = deque()
        self._beats: dict[str, Heartbeat] = {}
        self._rtcm: deque[Corrections] = deque()
        self._scheduled = False
        self._closed = False
        #: items not queued, by reason (any thread; read a copy)
        self.dropped: Counter[str] = Counter()
        #: drains that stopped at their slice bound with items left
        self.slices = 0

    def post(self, item: Item) -> bool:
        """Queue ``item`` (any thread); False if it was not queued (full, closed)."""
        with self._lock:
            if self._closed:
                return False
            if isinstance(item, Query):
                stop = item.key.endswith("/cmd/stop")
                queue, bound = (self._stops, STOPS_MAX) if stop else \
                    (self._commands, COMMANDS_MAX)
                if len(queue) >= bound:
                    self.dropped["stops_busy" if stop else "commands_busy"] += 1
                    return False
                queue.append(item)
            elif isinstance(item, Heartbeat):
                if item.user not in self._beats and len(self._beats) >= USERS_MAX:
                    self.dropped["heartbeats_users"] += 1
                    return False
                if item.user in self._beats:
                    self.dropped["heartbeats_coalesced"] += 1
                self._beats[item.user] = item
            else:
                if len(self._rtcm) >= RTCM_MAX:
                    self.dropped["rtcm_queue_full"] += 1
                    return False
                self._rtcm.append(item)
            if self._scheduled:
                return True
            self._scheduled = True
        try:
            self.loop.call_soon_threadsafe(self._drain)
        except RuntimeError:  # the loop is closed: we are shutting down
            return False
        return True

    def _take(self, n: int) -> list[Item]:
        """Up to ``n`` items: stops first, then heartbeats (the cheapest, and the
        link's life), then corrections and commands alternately."""
        with self._lock:
            out: list[Item] = []
            while self._stops and len(out) < n:
                out.append(self._stops.popleft())
            while self._beats and len(out) < n:
                out.append(self._beats.pop(next(iter(self._beats))))
            while (self._rtcm or self._commands) and len(out) < n:
                if self._rtcm:
                    out.append(self._rtcm.popleft())
                if self._commands and len(out) < n:
                    out.append(self._commands.popleft())
            return out

    def _drain(self) -> None:
        deadline = time.perf_counter() + SLICE_S
        handled = 0
        while handled < SLICE_ITEMS and time.perf_counter() < deadline:
            items = self._take(min(8, SLICE_ITEMS - handled))
            if not items:
                break
            for it in items:
                handled += 1
                try:
                    self.handle(it)
                except Exception as exc:  # one bad item never drops another
                    self.on_fault(it, exc)
        with self._lock:
            more = bool(self._stops or self._commands or self._beats or self._rtcm)
            if not more or self._closed:
                self._scheduled = False
                return
        self.slices += 1
        self.loop.call_soon(self._drain)  # the rest after the loop's other work

    def close(self) -> list[Query]:
        """Stop accepting; the queries not yet handled (they still need a reply)."""
        with self._lock:
            self._closed = True
            left = [*self._stops, *self._commands]
            self._stops.clear()
            self._commands.clear()
            self._beats.clear()
            self._rtcm.clear()
        return left
