"""``zarco decode LOG|-``: what the drivers make of a capture, one JSON line per sentence.

Like GPSD's ``gpsdecode``: every sentence the runtime's drivers accept is
printed on standard output as one JSON object; everything refused goes to
standard error with its reason (the same counter keys the drivers use:
``checksum``, ``no_checksum``, ``field``, ``unsupported``, ...).  Lines
starting with ``#`` (comments in GPSD's captures) and blank lines are
skipped.

The bytes take the drivers' own path: :class:`drivers.nmea.NmeaFramer`, then
the parser of the device that speaks the sentence type —
:func:`~drivers.gps_parser.parse_gps` (GGA, RMC, GLL, GNS, VTG, GST, ZDA, HDT,
THS),
:func:`~drivers.compass_parser.parse_compass` (HDG, HDM, ROT, XDR),
:func:`~drivers.thruster_protocol.parse_pzthr` / ``parse_pzths``.

Output keys (always ``kind`` = sentence type, ``talker``, ``n`` = input line
number, ``device`` = the driver that would read it):

==========  ====================================================================
GGA, RMC,   ``lat``, ``lon`` (degrees, south/west negative, absent without a
GLL, GNS    position), ``fix`` (none / single / dgps / rtk_float / rtk_fixed),
            ``time`` (UTC hh:mm:ss.ss), GGA/GNS ``alt``, ``sats``, ``hdop``,
            ``age``; RMC with a usable fix also ``speed`` (m/s), ``track`` (deg)
VTG         ``speed`` (m/s), ``track`` (deg true, absent if unknown)
GST         ``std_lat``, ``std_lon``, ``std_alt``, ``rms`` (m)
ZDA         ``time`` (ISO 8601 UTC), ``epoch`` (s since 1970)
HDT/THS/    ``heading_deg`` (true when ``true`` is true, else magnetic),
HDG/HDM     ``true``, ``raw_deg``, ``variation_deg``, ``deviation_deg``
ROT         ``rot_dpm`` (deg/min, + to starboard)
XDR         ``pitch_deg``, ``roll_deg`` (when present)
PZTHR       ``u1``, ``u2``;  PZTHS ``u1``, ``u2``, ``rpm1``, ``rpm2``, ``amps1``, ``amps2``
==========  ====================================================================
"""

from __future__ import annotations

import json
import math
import sys
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import IO, Any

from drivers.compass_parser import COMPASS_HANDLERS, parse_compass
from drivers.gps_parser import GPS_HANDLERS, parse_gps
from drivers.nmea import NmeaError, NmeaFramer, sentence_type
from drivers.thruster_protocol import parse_pzthr, parse_pzths
from zarco_core.messages import (
    Attitude,
    GpsErrorStats,
    GpsFix,
    GpsTime,
    GpsVelocity,
    Heading,
    RateOfTurn,
    ThrusterStatus,
)
from zarco_core.paths import readable_file


def _r(x: float | None, nd: int) -> float | None:
    return None if x is None else round(x, nd)


def _tod(utc_s: float | None) -> str | None:
    """Seconds of the UTC day → ``hh:mm:ss.ss``."""
    if utc_s is None:
        return None
    hh, rem = divmod(utc_s, 3600.0)
    mm, ss = divmod(rem, 60.0)
    return f"{int(hh):02d}:{int(mm):02d}:{ss:05.2f}"


def _deg(rad: float | None, nd: int = 6) -> float | None:
    return None if rad is None else round(math.degrees(rad), nd)


def message_fields(m: Any) -> dict[str, Any]:
    """The JSON fields of one bus message (None values are dropped later)."""
    if isinstance(m, GpsFix):
        return {"talker": m.talker, "lat": _r(m.lat_deg, 10), "lon": _r(m.lon_deg, 10),
                "fix": m.fix.label, "time": _tod(m.utc_s), "alt": m.alt_m,
                "sats": m.num_sats, "hdop": m.hdop, "age": m.age_s}
    if isinstance(m, GpsVelocity):
        return {"speed": _r(m.sog_mps, 4), "track": _deg(m.cog_rad, 4)}
    if isinstance(m, GpsErrorStats):
        return {"std_lat": m.std_lat_m, "std_lon": m.std_lon_m, "std_alt": m.std_alt_m,
                "rms": m.rms_m, "time": _tod(m.utc_s)}
    if isinstance(m, GpsTime):
        iso = datetime.fromtimestamp(m.utc_epoch_s, UTC).isoformat(timespec="milliseconds")
        return {"time": iso.replace("+00:00", "Z"), "epoch": round(m.utc_epoch_s, 3)}
    if isinstance(m, Heading):
        return {"heading_deg": _deg(m.heading_rad), "true": m.true, "raw_deg": m.raw_deg,
                "variation_deg": m.variation_deg, "deviation_deg": m.deviation_deg}
    if isinstance(m, RateOfTurn):
        return {"rot_dpm": round(math.degrees(m.rate_rps) * 60.0, 6)}
    if isinstance(m, Attitude):
        return {"pitch_deg": _deg(m.pitch_rad), "roll_deg": _deg(m.roll_rad)}
    if isinstance(m, ThrusterStatus):
        return {"u1": m.u1, "u2": m.u2, "rpm1": m.rpm1, "rpm2": m.rpm2,
                "amps1": m.amps1, "amps2": m.amps2}
    return {"message": type(m).__name__}  # pragma: no cover - a new message type


def is_compass_type(stype: str) -> bool:
    """A sentence type only the compass driver reads (HDG, HDM, ROT, XDR)."""
    return stype in COMPASS_HANDLERS and stype not in GPS_HANDLERS


def decode_sentence(line: str, variation_deg: float | None = None
                    ) -> tuple[str, dict[str, Any]]:
    """One framed sentence → (device, JSON fields), or ``NmeaError`` with the reason.

    The device is the driver that reads this sentence type (``gps``,
    ``compass``, ``thrusters``); unknown types go through the GPS parser so
    that framing and checksum problems are reported before ``unsupported``.
    """
    stype = sentence_type(line)
    if stype == "PZTHR":
        u1, u2 = parse_pzthr(line)
        return "thrusters", {"kind": "PZTHR", "u1": u1, "u2": u2}
    if stype == "PZTHS":
        return "thrusters", {"kind": "PZTHS", **message_fields(parse_pzths(line, 0.0))}
    if is_compass_type(stype):
        device, msgs = "compass", parse_compass(line, 0.0, "compass", variation_deg)
    else:
        device, msgs = "gps", parse_gps(line, 0.0, "gps", variation_deg)
    talker = line[1:3]
    out: dict[str, Any] = {"kind": stype, "talker": talker}
    for m in msgs:
        out.update(message_fields(m))
    return device, out


@dataclass(slots=True)
class Rejected:
    """Something refused: input line ``n``, ``reason`` (counter key), ``detail``, ``text``."""

    n: int
    reason: str
    detail: str
    text: str


@dataclass(slots=True)
class DecodeStats:
    accepted: Counter[str] = field(default_factory=Counter)
    rejected: Counter[str] = field(default_factory=Counter)
    comments: int = 0
    bytes_discarded: int = 0


def decode_lines(lines: Iterable[bytes], variation_deg: float | None = None,
                 stats: DecodeStats | None = None) -> Iterator[dict[str, Any] | Rejected]:
    """Decode raw input lines (bytes, with or without their line end).

    Yields one dict per accepted sentence (with ``n`` and ``device``) and one
    :class:`Rejected` per refused sentence or discarded byte run, in input order.
    """
    st = stats if stats is not None else DecodeStats()
    framer = NmeaFramer()
    for n, raw in enumerate(lines, 1):
        body = raw.rstrip(b"\r\n")
        if not body.strip():
            continue
        if body.startswith(b"#"):
            st.comments += 1
            continue
        before = (framer.bytes_discarded, framer.garbage_lines, framer.overlong,
                  framer.restarts)
        sentences = framer.feed(body + b"\r\n")
        lost = framer.bytes_discarded - before[0]
        if lost:
            st.bytes_discarded += lost
            if framer.garbage_lines > before[1]:
                why = "non-printable or non-ASCII bytes in a sentence"
            elif framer.overlong > before[2]:
                why = f"sentence longer than {framer.max_len} characters"
            elif framer.restarts > before[3]:
                why = "sentence cut short by a new start character"
            else:
                why = "bytes outside any sentence"
            st.rejected["framing"] += 1
            yield Rejected(n, "framing", f"{lost} bytes discarded: {why}",
                           body[:80].decode("ascii", "backslashreplace"))
        for line in sentences:
            try:
                device, out = decode_sentence(line, variation_deg)
            except NmeaError as exc:
                st.rejected[exc.reason] += 1
                yield Rejected(n, exc.reason, exc.detail, line[:80])
                continue
            st.accepted[out["kind"]] += 1
            yield {"n": n, "device": device, **{k: v for k, v in out.items() if v is not None}}


def decode_stream(src: IO[bytes], out: IO[str], err: IO[str], name: str,
                  variation_deg: float | None = None, summary: bool = False) -> DecodeStats:
    """Decode ``src`` to JSON lines on ``out``; refusals on ``err`` as
    ``NAME:LINE: reason: detail: 'text'``."""
    stats = DecodeStats()
    write_out, write_err = out.write, err.write
    for item in decode_lines(src, variation_deg, stats):
        if isinstance(item, Rejected):
            detail = f": {item.detail}" if item.detail else ""
            write_err(f"{name}:{item.n}: {item.reason}{detail}: {item.text!r}\n")
        else:
            write_out(json.dumps(item, separators=(",", ":")) + "\n")
    if summary:
        acc = " ".join(f"{k}={v}" for k, v in sorted(stats.accepted.items()))
        rej = " ".join(f"{k}={v}" for k, v in sorted(stats.rejected.items()))
        write_err(f"{name}: accepted {sum(stats.accepted.values())} ({acc or '-'}); "
                  f"refused {sum(stats.rejected.values())} ({rej or '-'}); "
                  f"{stats.bytes_discarded} bytes discarded; {stats.comments} comment lines\n")
    return stats


def main_decode(path: str, variation_deg: float | None = None, summary: bool = False,
                out: IO[str] | None = None, err: IO[str] | None = None) -> int:
    """``zarco decode``: 0 on success, 1 if reading the input fails; a path that
    cannot be read at all raises PathError (exit 2)."""
    out = out or sys.stdout
    err = err or sys.stderr
    if path != "-":
        readable_file(path)
    try:
        if path == "-":
            decode_stream(sys.stdin.buffer, out, err, "-", variation_deg, summary)
        else:
            with open(path, "rb") as fh:
                decode_stream(fh, out, err, path, variation_deg, summary)
    except BrokenPipeError:  # `zarco decode LOG | head`
        return 0
    except OSError as exc:
        err.write(f"zarco decode: {path}: {exc.strerror or exc}\n")
        return 1
    return 0
