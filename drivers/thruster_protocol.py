"""The thruster controller's protocol (the project's own, NMEA-framed; docs/protocols.md).

::

    $PZTHR,U1,U2*hh                    runtime → controller, at the control rate
    $PZTHS,U1,U2,RPM1,RPM2,A1,A2*hh    controller → runtime, status

U1/U2 are the port (1) and starboard (2) commands, -100.0..100.0 with one
decimal; RPM signed shaft speed (rev/min), A motor current (amperes, a
magnitude: never negative).  Framing and checksum go through
:func:`drivers.nmea.split_checked`.  Numbers must be plain decimals: no
exponent, ``nan`` or ``inf``.  Plausible values only: a command beyond ±100,
a shaft speed beyond ±``RPM_MAX`` or a current outside [0, ``AMPS_MAX``] is
``NmeaError("range")`` (never clamped); a field count other than the
sentence's is ``NmeaError("field")``.
"""

from __future__ import annotations

import math

from drivers.nmea import NmeaError, field_float, field_range, format_sentence, split_checked
from zarco_core.messages import ThrusterStatus

#: command limit, percent of full thrust
U_MAX = 100.0
#: largest shaft speed a status may report, rev/min
RPM_MAX = 100_000.0
#: largest motor current a status may report, amperes
AMPS_MAX = 1000.0


def _clamp_command(u: float, name: str) -> float:
    """Clamp to ±U_MAX and round to the wire's one decimal (no ``-0.0``)."""
    if not math.isfinite(u):
        raise ValueError(f"{name} must be finite, got {u!r}")
    return round(min(U_MAX, max(-U_MAX, float(u))), 1) + 0.0


def _finite(*values: float) -> None:
    for v in values:
        if not math.isfinite(v):
            raise ValueError(f"value must be finite, got {v!r}")


def encode_pzthr(u1: float, u2: float) -> bytes:
    """``$PZTHR,U1,U2*hh\\r\\n``: commands clamped to ±100, one decimal.

    Raises ValueError for NaN or infinite commands (the caller decides what
    a non-finite command means; it is never put on the wire).
    """
    a, b = _clamp_command(u1, "u1"), _clamp_command(u2, "u2")
    return format_sentence(f"PZTHR,{a:.1f},{b:.1f}")


def _command(s: str, name: str) -> float:
    u = field_float(s, name)
    if u is None:
        raise NmeaError("field", f"{name} empty")
    if not -U_MAX <= u <= U_MAX:
        raise NmeaError("range", f"{name}={u} outside ±{U_MAX:g}")
    return u


def _checked(line: str, address: str, n: int) -> list[str]:
    got, fields = split_checked(line)
    if got != address:
        raise NmeaError("unsupported", got)
    if len(fields) != n:
        raise NmeaError("field", f"{address}: {len(fields)} fields, want {n}")
    return fields


def parse_pzthr(line: str) -> tuple[float, float]:
    """``$PZTHR`` → (u1, u2).  Strict: checksum, exactly 2 fields, -100..100."""
    f = _checked(line, "PZTHR", 2)
    return _command(f[0], "u1"), _command(f[1], "u2")


def encode_pzths(u1: float, u2: float, rpm1: float, rpm2: float,
                 a1: float, a2: float) -> bytes:
    """``$PZTHS,U1,U2,RPM1,RPM2,A1,A2*hh\\r\\n`` (u .1f, rpm .0f, amperes .2f).

    Commands are clamped like :func:`encode_pzthr`; non-finite values raise
    ValueError.
    """
    _finite(rpm1, rpm2, a1, a2)
    a, b = _clamp_command(u1, "u1"), _clamp_command(u2, "u2")
    r1, r2 = round(rpm1) + 0.0, round(rpm2) + 0.0
    c1, c2 = round(a1, 2) + 0.0, round(a2, 2) + 0.0
    return format_sentence(f"PZTHS,{a:.1f},{b:.1f},{r1:.0f},{r2:.0f},{c1:.2f},{c2:.2f}")


def parse_pzths(line: str, t: float) -> ThrusterStatus:
    """``$PZTHS`` → ThrusterStatus at runtime time ``t``.  Exactly 6 fields."""
    f = _checked(line, "PZTHS", 6)
    u1, u2 = _command(f[0], "u1"), _command(f[1], "u2")
    rest = []
    for s, name, lo, hi in ((f[2], "rpm1", -RPM_MAX, RPM_MAX), (f[3], "rpm2", -RPM_MAX, RPM_MAX),
                            (f[4], "amps1", 0.0, AMPS_MAX), (f[5], "amps2", 0.0, AMPS_MAX)):
        v = field_range(s, name, lo, hi)
        if v is None:
            raise NmeaError("field", f"{name} empty")
        rest.append(v)
    return ThrusterStatus(t, u1, u2, *rest)
