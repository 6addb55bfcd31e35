"""NMEA 0183 framing, checksums and strict sentence parsing.

The checksum is the XOR of every character between ``$``/``!`` and ``*``,
written as two upper-case hex digits (NMEA 0183 §5.3).  Every sentence the
runtime uses must carry a valid checksum (DESIGN.md §7): pynmea2's default
parse accepts sentences without one, so :func:`parse_sentence` checks first.
"""

from __future__ import annotations


class NmeaError(ValueError):
    """A sentence was rejected. ``reason`` is a short counter key."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail


def nmea_checksum(body: str) -> int:
    """XOR checksum of ``body`` (the text between ``$`` and ``*``)."""
    cs = 0
    for ch in body.encode("ascii"):
        cs ^= ch
    return cs


def format_sentence(body: str, start: str = "$") -> bytes:
    """Frame ``body`` as ``$body*hh\\r\\n`` bytes."""
    return f"{start}{body}*{nmea_checksum(body):02X}\r\n".encode("ascii")
