"""The shore link's sender thread: every zenoh put and reply, in order.

No zenoh call is ever made on the event loop (a slow network cannot hold the
control loop) nor on zenoh's own callback threads.  Telemetry and replies
have their own bounds, so that a flood of commands (each answered) cannot
crowd the telemetry out, nor telemetry the replies: a telemetry object
beyond :data:`PUTS_MAX` waiting is dropped and counted; a reply beyond
:data:`REPLIES_MAX` waiting is dropped and counted, and its query released
(zenoh then ends the client's ``get`` with no reply rather than letting it
wait for its timeout).
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
from typing import Any

log = logging.getLogger("zarco.shore")

#: telemetry objects waiting to be put
PUTS_MAX = 1024
#: replies waiting to be sent
REPLIES_MAX = 8192


class Sender:
    """Queues from any thread; one thread makes the zenoh calls."""

    def __init__(self, telemetry: tuple[str, ...]) -> None:
        self._q: queue.SimpleQueue[tuple[Any, ...] | None] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._waiting = {"put": 0, "reply": 0}
        #: written under the lock (read a copy with :meth:`counters`)
        self._counters: dict[str, int] = {**{f"{k}_sent": 0 for k in telemetry},
                                          "replies_sent": 0, "send_errors": 0,
                                          "telemetry_dropped": 0, "replies_dropped": 0}
        self._thread: threading.Thread | None = None

    def counters(self) -> dict[str, int]:
        with self._lock:
            return dict(self._counters)

    def _admit(self, kind: str, bound: int) -> bool:
        with self._lock:
            if self._waiting[kind] >= bound:
                self._counters["telemetry_dropped" if kind == "put" else "replies_dropped"] += 1
                return False
            self._waiting[kind] += 1
            return True

    def put(self, key: str, payload: str) -> None:
        """Queue a telemetry put on ``key`` (a publisher's short name)."""
        if self._admit("put", PUTS_MAX):
            self._q.put(("put", key, payload))

    def reply(self, query: Any, key: str, payload: str) -> None:
        """Queue the one reply to ``query``."""
        if self._admit("reply", REPLIES_MAX):
            self._q.put(("reply", query, key, payload))
        else:
            with contextlib.suppress(Exception):
                query.drop()

    def start(self, publishers: dict[str, Any]) -> None:
        self._thread = threading.Thread(target=self._run, args=(publishers,),
                                        name="zarco-shore-send", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Send what waits, then end the thread (a worker thread: this blocks)."""
        t, self._thread = self._thread, None
        if t is not None:
            self._q.put(None)
            t.join(timeout_s)

    def _run(self, pubs: dict[str, Any]) -> None:
        while True:
            item = self._q.get()
            if item is None:
                return
            kind = item[0]
            ok = False
            try:
                if kind == "put":
                    pubs[item[1]].put(item[2])
                else:  # ("reply", query, key, payload)
                    q = item[1]
                    try:
                        q.reply(item[2], item[3])
                    finally:
                        q.drop()
                ok = True
            except Exception as exc:  # a closed session, a dropped query
                log.debug("shore: send failed: %s", exc)
            with self._lock:
                self._waiting[kind] -= 1
                if not ok:
                    self._counters["send_errors"] += 1
                elif kind == "put":
                    self._counters[f"{item[1]}_sent"] += 1
                else:
                    self._counters["replies_sent"] += 1
