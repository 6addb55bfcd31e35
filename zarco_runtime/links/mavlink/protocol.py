"""MAVLink conventions of the boat: the dialect, the custom mode numbers, the
thruster ↔ PWM and joystick ↔ thruster mappings, status texts.

The endpoint speaks MAVLink 2 with pymavlink's generated ``common`` dialect
(``pymavlink.dialects.v20.common``).  pymavlink's ``mavutil`` picks its global
dialect from environment variables when it is first imported; they are set here
(if unset) to MAVLink 2 / ``common`` so that its transports do not load the
much larger ``all`` dialect.  The endpoint never relies on that global: every
connection gets its own ``common.MAVLink`` object.

Custom modes (HEARTBEAT ``custom_mode``, DO_SET_MODE ``param2``) follow
ArduPilot Rover's numbers for the same behaviour, so that an operator used to
Rover reads them alike:

=============  ===========  ====================================================
mode           custom_mode  (Rover name) meaning
=============  ===========  ====================================================
``manual``     0            (MANUAL) the operator's thrust, held for the lease
``idle``       4            (HOLD) zero thrust; disarmed
``hold``       5            (LOITER) station keeping at a point
``follow``     6            (FOLLOW) following the AUV
``lines``      10           (AUTO) the loaded mission, line by line
``return``     11           (RTL) go home, then hold
=============  ===========  ====================================================

Thrusters (SERVO_OUTPUT_RAW): the commanded U1 (port) on ``servo1_raw`` and U2
(starboard) on ``servo2_raw``, −100..+100 % mapped linearly to 1100..1900 µs,
1500 µs at zero thrust: ``pwm = 1500 + 4·U``.

Joystick (MANUAL_CONTROL, manual mode): ``x`` is forward (+1000) / astern
(−1000), ``r`` the turn, +1000 to starboard (clockwise, as QGroundControl, PX4
and ArduPilot send it); they are mixed as ``U1 = (x + r) / 10``, ``U2 = (x − r)
/ 10`` (%), each clipped to ±100; an axis marked invalid (INT16_MAX) counts as 0.
"""

from __future__ import annotations

import math
import os

os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "common")

from pymavlink.dialects.v20 import common as mav

from zarco_core.messages import Mode

__all__ = ["CUSTOM_MODE", "MODE_OF_CUSTOM", "base_mode", "event_severity", "mav", "mix_manual",
           "text_chunks", "thrust_to_pwm", "whole"]

#: custom_mode number of each supervisor mode (see the module docstring)
CUSTOM_MODE: dict[Mode, int] = {
    Mode.MANUAL: 0,
    Mode.IDLE: 4,
    Mode.HOLD: 5,
    Mode.FOLLOW: 6,
    Mode.LINES: 10,
    Mode.RETURN: 11,
}
MODE_OF_CUSTOM: dict[int, Mode] = {v: k for k, v in CUSTOM_MODE.items()}

#: PWM (µs) at zero thrust, and per % of thrust
PWM_NEUTRAL_US = 1500
PWM_PER_PERCENT = 4.0
INT16_MAX = 32767
UINT16_MAX = 65535


def whole(x: float, lo: int, hi: int) -> int | None:
    """``x`` (a command's float parameter) as an integer within ``lo..hi``; None
    when it is not a whole number there (NaN, infinite, fractional, out of range)."""
    if not math.isfinite(x) or x != math.floor(x) or not lo <= x <= hi:
        return None
    return int(x)


def thrust_to_pwm(u: float) -> int:
    """A thruster command (−100..100 %) as a servo pulse (µs): 1100..1900, 1500 at 0."""
    if u != u:  # NaN
        u = 0.0
    u = max(-100.0, min(100.0, u))
    return round(PWM_NEUTRAL_US + PWM_PER_PERCENT * u)


def mix_manual(x: int, r: int) -> tuple[float, float]:
    """MANUAL_CONTROL axes (−1000..1000; ``x`` forward, ``r`` turn to starboard)
    → (U1 port, U2 starboard) in % (−100..100)."""
    fx = 0.0 if x == INT16_MAX else max(-1000.0, min(1000.0, float(x)))
    fr = 0.0 if r == INT16_MAX else max(-1000.0, min(1000.0, float(r)))
    u1 = max(-100.0, min(100.0, (fx + fr) / 10.0))
    u2 = max(-100.0, min(100.0, (fx - fr) / 10.0))
    return u1, u2


def base_mode(mode: Mode, armed: bool) -> int:
    """HEARTBEAT ``base_mode`` flags for ``mode``."""
    flags = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if armed:
        flags |= mav.MAV_MODE_FLAG_SAFETY_ARMED
    if mode is Mode.MANUAL:
        flags |= mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    elif mode is Mode.LINES:
        flags |= mav.MAV_MODE_FLAG_AUTO_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
    elif mode in (Mode.HOLD, Mode.FOLLOW, Mode.RETURN):
        flags |= mav.MAV_MODE_FLAG_GUIDED_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
    return int(flags)


#: STATUSTEXT severity per Event kind (refusals and failsafe entries are raised below)
SEVERITY = {
    "failsafe": mav.MAV_SEVERITY_WARNING,
    "fault": mav.MAV_SEVERITY_ERROR,
    "component": mav.MAV_SEVERITY_ERROR,
    "mode": mav.MAV_SEVERITY_NOTICE,
    "mission": mav.MAV_SEVERITY_INFO,
    "ack": mav.MAV_SEVERITY_INFO,
    "param": mav.MAV_SEVERITY_NOTICE,
    "link": mav.MAV_SEVERITY_WARNING,
}


def event_severity(kind: str, text: str) -> int:
    """STATUSTEXT severity of an event: failsafe entries are critical (a GCS speaks
    them), refusals warnings, the rest by kind."""
    if kind == "failsafe" and "action" in text:
        return int(mav.MAV_SEVERITY_CRITICAL)
    if kind == "ack" and ": refused" in text:
        return int(mav.MAV_SEVERITY_WARNING)
    return int(SEVERITY.get(kind, mav.MAV_SEVERITY_INFO))


#: characters in one STATUSTEXT
STATUSTEXT_LEN = 50
#: most chunks of one text (MAVLink 2's ``chunk_seq`` is a byte: at most 256); a
#: longer text is cut, ending in "..."
STATUSTEXT_MAX_CHUNKS = 10
#: the longest text sent whole: one character short of the last chunk, so a cut
#: text ends with a short chunk and needs no empty one
STATUSTEXT_MAX_LEN = STATUSTEXT_MAX_CHUNKS * STATUSTEXT_LEN - 1
ELLIPSIS = b"..."
#: STATUSTEXT is ASCII for most ground stations: the runtime's few other characters
ASCII = str.maketrans({"≥": ">=", "≤": "<=", "°": " deg", "×": "x", "→": "->", "←": "<-",
                       "−": "-", "–": "-", "—": "-", "σ": "sigma", "ψ": "psi", "±": "+/-",
                       "·": "*", "…": "..."})
#: control characters (a NUL would end the text early; escapes reach a terminal)
CONTROL = bytes(range(32)) + b"\x7f"
UNPRINTABLE = bytes.maketrans(CONTROL, b"?" * len(CONTROL))


def text_chunks(text: str) -> list[bytes]:
    """``text`` as STATUSTEXT chunks of at most 50 printable ASCII characters
    (others spelt out, or ``?``).  MAVLink 2 joins chunks sharing an ``id`` by
    ``chunk_seq``; a chunk shorter than 50 ends the text, so a long text of a
    whole number of chunks gets an empty last one.  At most
    :data:`STATUSTEXT_MAX_CHUNKS` chunks: a longer text is cut to
    :data:`STATUSTEXT_MAX_LEN` characters, the last three ``...``."""
    b = text.translate(ASCII).encode("ascii", "replace").translate(UNPRINTABLE)
    if len(b) > STATUSTEXT_MAX_LEN:
        b = b[:STATUSTEXT_MAX_LEN - len(ELLIPSIS)] + ELLIPSIS
    out = [b[i:i + STATUSTEXT_LEN] for i in range(0, len(b), STATUSTEXT_LEN)] or [b""]
    if len(out) > 1 and len(out[-1]) == STATUSTEXT_LEN:
        out.append(b"")
    return out
