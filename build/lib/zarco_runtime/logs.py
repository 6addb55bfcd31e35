"""Logging for ``zarco``: to the terminal, or to journald with priorities.

Under systemd, stderr is connected to the journal (``JOURNAL_STREAM`` is set);
each line then starts with its ``sd-daemon(3)`` priority prefix (``<3>`` error,
``<4>`` warning, ``<6>`` info, ``<7>`` debug) so that ``journalctl -p warning``
filters as expected, and carries no timestamp of its own (the journal adds
one).  A multi-line record (a traceback) is prefixed on every line.
"""

from __future__ import annotations

import logging
import os
import sys

#: logging level → syslog priority
PRIORITY = {logging.CRITICAL: 2, logging.ERROR: 3, logging.WARNING: 4, logging.INFO: 6,
            logging.DEBUG: 7}


def priority(levelno: int) -> int:
    for level in sorted(PRIORITY, reverse=True):
        if levelno >= level:
            return PRIORITY[level]
    return 7


class JournalFormatter(logging.Formatter):
    """``<priority>logger: message``, every line of it."""

    def __init__(self) -> None:
        super().__init__("%(name)s: %(message)s")

    def format(self, record: logging.LogRecord) -> str:
        p = f"<{priority(record.levelno)}>"
        return "\n".join(p + line for line in super().format(record).splitlines())


def under_journal() -> bool:
    """Is stderr the journal?  (``JOURNAL_STREAM`` = ``device:inode`` of stderr.)"""
    js = os.environ.get("JOURNAL_STREAM")
    if not js:
        return False
    try:
        st = os.fstat(sys.stderr.fileno())
    except (OSError, ValueError):
        return False
    dev, _, ino = js.partition(":")
    return f"{st.st_dev}" == dev and f"{st.st_ino}" == ino


def setup(verbose: bool, service: bool = False) -> None:
    """Log to stderr: DEBUG with ``verbose``; INFO for the vessel's service (mode
    changes, failsafes, acknowledgements are worth keeping); else WARNING."""
    level = logging.DEBUG if verbose else logging.INFO if service else logging.WARNING
    handler = logging.StreamHandler(sys.stderr)
    if under_journal():
        handler.setFormatter(JournalFormatter())
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)
