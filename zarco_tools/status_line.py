"""A progress line for a long job (a replay, a simulation): rewritten in place
on a terminal, at most every ``TTY_PERIOD_S``; one line every ``LOG_PERIOD_S``
otherwise (a log, a pipe).  It writes to the stderr of when the job runs, not
to the one of when a module was imported (a program or a test harness may
swap it, or close the one it had)."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

#: on a terminal, the line is rewritten at most this often (s)
TTY_PERIOD_S = 0.2
#: elsewhere, a new line at most this often (s)
LOG_PERIOD_S = 5.0


class TtyLine:
    """One progress line on ``stream`` (default: the current ``sys.stderr``);
    ``clock`` (s) paces it."""

    def __init__(self, stream: Any = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.clock = clock
        self.last = -1e9

    def due(self, force: bool = False) -> bool:
        """Whether a line is due now (``force``: whatever the pace); a due line
        counts as written."""
        now = self.clock()
        if not force and now - self.last < (TTY_PERIOD_S if self.tty else LOG_PERIOD_S):
            return False
        self.last = now
        return True

    def write(self, msg: str) -> None:
        """Show ``msg``: over the line on a terminal, as a new line elsewhere."""
        self.stream.write(("\r" + msg) if self.tty else (msg + "\n"))
        self.stream.flush()

    def end(self, tail: str) -> None:
        """On a terminal, finish the line with ``tail``; elsewhere nothing."""
        if self.tty:
            self.stream.write(tail)
            self.stream.flush()
