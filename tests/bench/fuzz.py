"""Fuzz the NMEA driver paths with seeded mutations of real receivers' lines.

    python tests/bench/fuzz.py [--lines 100000] [--seed 1]

Seed corpus: every sentence of ``tests/data/gpsd-logs/*.log`` (GPSD's real
captures: GGA, RMC, VTG, GST, ZDA, HDT, HDM, ROT, XDR, GSV, ...) plus the
sentences the project's own devices speak and no capture holds: the
simulated compass's HDG/ROT/XDR and ``$PZTHR``/``$PZTHS`` of the thruster
controller.

Each mutated line is one to three of: bit flips, truncation, insertion of
random bytes (printable or binary), deletion, field swap / duplication /
deletion, a field replaced by a nasty value (``nan``, ``1e9``, ``-``,
a 40-digit number, ...), splicing with another line, lower-case checksum,
missing checksum.  With probability ½ the checksum is then recomputed over
the mutated content, so that the field parsers, not only the checksum
check, see the damage.

Every mutated line (plus CR LF) goes through each driver path exactly as the
drivers run it: :class:`~drivers.nmea.NmeaFramer` then ``parse_gps`` (GPS
driver), ``parse_compass`` (compass driver), ``parse_buoy`` (buoy radio),
``parse_pzths`` (thruster driver) and ``parse_pzthr`` (the thruster
controller's side of the link).  Counted:

* ``escaped_exceptions`` — anything but ``NmeaError`` out of a parser (must be 0);
* ``bad_checksum_used`` — a sentence accepted although an independent check
  (last ``*``, exactly two hex digits, XOR of the bytes between the start
  character and that ``*``) says its checksum is bad or missing (must be 0);
* ``implausible_used`` — a message out of an accepted sentence whose values
  an independent check (:func:`implausible`, on the bus messages) finds
  outside their physical range (must be 0).

Then the out-of-range set: every numeric field of one valid sentence of
each type the drivers read (GGA, RMC, GLL, GNS, VTG, GST, ZDA, HDT, THS,
HDG, HDM, ROT, XDR, ``$PZBAE``, ``$PZBST``, ``$PZTHR``, ``$PZTHS``) replaced
by values just beyond, far beyond and one turn beyond its physical range
(heading 360.5, 400, 720.5, 999999, -0.5; ROT 1e6 °/min; SOG 99999 kn;
HDOP -5; year 9999; ...), checksum recomputed: ``out_of_range.accepted``
counts the ones a driver path took (must be 0).

Ends by printing one JSON line of its figures.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import re
import sys
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
# the repository first (this file's own directory would make "hil" this script)
sys.path[:] = [str(ROOT)] + [p for p in sys.path if p != str(ROOT)]

from drivers.buoy_parser import parse_buoy  # noqa: E402
from drivers.compass_parser import parse_compass  # noqa: E402
from drivers.gps_parser import parse_gps  # noqa: E402
from drivers.nmea import NmeaError, NmeaFramer  # noqa: E402
from drivers.thruster_protocol import parse_pzthr, parse_pzths  # noqa: E402
from zarco_core.auv_messages import AcousticEvent, BuoyStatus  # noqa: E402
from zarco_core.messages import (  # noqa: E402
    Attitude,
    GpsErrorStats,
    GpsFix,
    GpsTime,
    GpsVelocity,
    Heading,
    RateOfTurn,
    ThrusterStatus,
)

LOGS = ROOT / "tests" / "data" / "gpsd-logs"

#: sentences of the project's own devices (no GPSD capture has them)
OWN_SENTENCES = [
    "$HCHDG,98.3,,,2.0,W*", "$HCHDG,359.9,0.5,E,2.0,W*", "$TIROT,-12.34,A*",
    "$YXXDR,A,0.4,D,PTCH,A,-1.2,D,ROLL*", "$HCHDM,218.6,M*", "$HEHDT,123.4,T*",
    "$HETHS,123.4,A*", "$PZTHR,12.5,-3.0*", "$PZTHR,-100.0,100.0*", "$PZTHR,0.0,0.0*",
    "$PZTHS,12.5,-3.0,1500,-700,3.20,1.05*", "$PZTHS,0.0,0.0,0,0,0.00,0.00*",
    "$GNGGA,120000.00,4111.10000000,N,00842.30000000,W,4,14,0.7,0.000,M,0.000,M,1.0,0000*",
    "$GNRMC,120000.00,A,4111.10000000,N,00842.30000000,W,1.944,12.34,010626,,,R*",
    "$GNGST,120000.00,0.015,0.015,0.015,0.0,0.015,0.015,0.030*",
    "$GNZDA,120000.00,01,06,2026,00,00*",
    "$GNGLL,4111.10000000,N,00842.30000000,W,120000.00,A,R*",
    "$GNGNS,120000.00,4111.10000000,N,00842.30000000,W,RR,14,0.7,0.000,0.000,1.0,0000,S*",
    "$PZBAE,101502.123456,010626,I,2,18.5*", "$PZBAE,235960.000001,311226,R,9999,-3.5*",
    "$PZBST,100001.00,010626,4111.100000,N,00842.300000,W,12.60,0*",
    "$PZBST,100001.00,010626,,,,,11.95,3*",
]

NASTY = ["", "nan", "NaN", "inf", "-inf", "1e9", "1E-3", "-", "+", ".", "..", "-0", "0x1F",
         "9" * 40, "-" + "9" * 30, " 1.0", "1.0 ", "1_0", "٣", "A", "AA", "*", ",", "$", "!",
         "\x00", "\xff", "999999", "-999999.999", "235960", "246000.00", "4807.038.1",
         "18100.000", "9060.000", "00000", "E", "W", "N", "S", "T", "M", "V"]
_FIELD_RE = re.compile(rb",")
_CHK_RE = re.compile(rb"\*[0-9A-Fa-f]{0,2}$")


def checksum(body: bytes) -> int:
    cs = 0
    for b in body:
        cs ^= b
    return cs


def _frame(body: str) -> bytes:
    b = body.encode()
    return b"$" + b + b"*%02X" % checksum(b)


def load_corpus(seed: int = 0) -> dict[str, list[bytes]]:
    """Seed lines by the driver that reads them, as bytes without CR LF.

    ``gps``: every sentence of the GNSS captures (including the types no
    driver reads: GSV, GSA, ...); ``compass``: pypilot's HDM/ROT/XDR and the
    simulated compass's sentences; ``thrusters``: ``$PZTHR``/``$PZTHS`` with
    seeded values over their whole range.
    """
    pools: dict[str, list[bytes]] = {"gps": [], "compass": [], "thrusters": [], "buoy": []}
    for log in sorted(LOGS.glob("*.log")):
        pool = pools["compass" if log.name == "pypilot.log" else "gps"]
        for raw in log.read_bytes().splitlines():
            if raw.startswith((b"$", b"!")):
                pool.append(raw.rstrip(b"\r\n"))
    for s in OWN_SENTENCES:
        body = s[1:-1]
        pool = "buoy" if body.startswith("PZB") else "thrusters" if body.startswith("PZ") else (
            "gps" if body.startswith("GN") else "compass")
        pools[pool].append(_frame(body))
    rng = random.Random(seed)
    for _ in range(200):
        u1, u2 = (round(rng.uniform(-100, 100), 1) for _ in range(2))
        pools["thrusters"].append(_frame(f"PZTHR,{u1:.1f},{u2:.1f}"))
        pools["thrusters"].append(_frame(
            f"PZTHS,{u1:.1f},{u2:.1f},{rng.randint(-3000, 3000)},{rng.randint(-3000, 3000)},"
            f"{rng.uniform(0, 20):.2f},{rng.uniform(0, 20):.2f}"))
        pools["compass"].append(_frame(
            f"HCHDG,{rng.uniform(0, 360):.1f},,,{rng.uniform(0, 20):.1f},{rng.choice('EW')}"))
        pools["compass"].append(_frame(f"TIROT,{rng.uniform(-900, 900):.2f},A"))
        pools["buoy"].append(_frame(
            f"PZBAE,{rng.randrange(24):02d}{rng.randrange(60):02d}{rng.randrange(60):02d}."
            f"{rng.randrange(10**6):06d},{rng.randrange(1, 29):02d}{rng.randrange(1, 13):02d}"
            f"{rng.randrange(100):02d},{rng.choice('IR')},{rng.randrange(10)},"
            f"{rng.uniform(-10, 60):.1f}"))
    return pools


#: share of seed lines drawn from each pool
POOL_WEIGHTS = {"gps": 0.45, "compass": 0.2, "thrusters": 0.2, "buoy": 0.15}


def valid_checksum(frame: str) -> bool:
    """The independent oracle: last ``*`` followed by exactly two hex digits that
    equal the XOR of every byte between the start character and that ``*``."""
    star = frame.rfind("*")
    if star < 1 or len(frame) - star != 3:
        return False
    hh = frame[star + 1:]
    if any(c not in "0123456789ABCDEFabcdef" for c in hh):
        return False
    try:
        body = frame[1:star].encode("ascii")
    except UnicodeEncodeError:
        return False
    return checksum(body) == int(hh, 16)


def _strip_checksum(line: bytes) -> bytes:
    return _CHK_RE.sub(b"", line)


def _recompute(line: bytes) -> bytes:
    """Checksum over whatever the (mutated) content now is."""
    core = _strip_checksum(line)
    if not core:
        return core
    start = 1 if core[:1] in (b"$", b"!") else 0
    return core + b"*%02X" % checksum(core[start:])


class Mutator:
    def __init__(self, corpus: list[bytes], rng: random.Random) -> None:
        self.corpus = corpus  # every seed line (for splicing)
        self.rng = rng
        self.ops: list[Callable[[bytes], bytes]] = [
            self.bit_flip, self.truncate, self.insert_random, self.insert_binary,
            self.delete_bytes, self.swap_fields, self.dup_field, self.drop_field,
            self.nasty_field, self.splice, self.lower_checksum, self.no_checksum,
            self.wrong_start,
        ]
        self.used: Counter[str] = Counter()

    def bit_flip(self, s: bytes) -> bytes:
        b = bytearray(s)
        for _ in range(self.rng.randint(1, 3)):
            if b:
                i = self.rng.randrange(len(b))
                b[i] ^= 1 << self.rng.randrange(8)
        return bytes(b)

    def truncate(self, s: bytes) -> bytes:
        return s[: self.rng.randrange(len(s) + 1)] if s else s

    def insert_random(self, s: bytes) -> bytes:
        i = self.rng.randrange(len(s) + 1)
        junk = bytes(self.rng.randrange(0x20, 0x7F) for _ in range(self.rng.randint(1, 8)))
        return s[:i] + junk + s[i:]

    def insert_binary(self, s: bytes) -> bytes:
        i = self.rng.randrange(len(s) + 1)
        return s[:i] + self.rng.randbytes(self.rng.randint(1, 6)) + s[i:]

    def delete_bytes(self, s: bytes) -> bytes:
        if not s:
            return s
        i = self.rng.randrange(len(s))
        return s[:i] + s[i + self.rng.randint(1, 4):]

    def _fields(self, s: bytes) -> tuple[list[bytes], bytes]:
        core = _strip_checksum(s)
        return core.split(b","), s[len(core):]

    def swap_fields(self, s: bytes) -> bytes:
        f, tail = self._fields(s)
        if len(f) > 2:
            i, j = self.rng.sample(range(1, len(f)), 2)
            f[i], f[j] = f[j], f[i]
        return b",".join(f) + tail

    def dup_field(self, s: bytes) -> bytes:
        f, tail = self._fields(s)
        i = self.rng.randrange(len(f))
        f.insert(i, f[i])
        return b",".join(f) + tail

    def drop_field(self, s: bytes) -> bytes:
        f, tail = self._fields(s)
        if len(f) > 1:
            del f[self.rng.randrange(1, len(f))]
        return b",".join(f) + tail

    def nasty_field(self, s: bytes) -> bytes:
        f, tail = self._fields(s)
        if len(f) > 1:
            f[self.rng.randrange(1, len(f))] = self.rng.choice(NASTY).encode("utf-8")
        return b",".join(f) + tail

    def splice(self, s: bytes) -> bytes:
        other = self.rng.choice(self.corpus)
        return s[: self.rng.randrange(len(s) + 1)] + other[self.rng.randrange(len(other) + 1):]

    def lower_checksum(self, s: bytes) -> bytes:
        return s.lower() if self.rng.random() < 0.2 else s[:-2] + s[-2:].lower()

    def no_checksum(self, s: bytes) -> bytes:
        return _strip_checksum(s)

    def wrong_start(self, s: bytes) -> bytes:
        return self.rng.choice([b"!", b"", b"$$", b"#"]) + s[1:]

    def mutate(self, s: bytes) -> bytes:
        for _ in range(self.rng.choice((1, 1, 1, 2, 2, 3))):
            op = self.rng.choice(self.ops)
            self.used[op.__name__] += 1
            s = op(s)
        if self.rng.random() < 0.5:
            self.used["checksum_recomputed"] += 1
            s = _recompute(s)
        return s


ParserFn = Callable[[str], Any]
PATHS: dict[str, ParserFn] = {
    "gps": lambda line: parse_gps(line, 0.0),
    "compass": lambda line: parse_compass(line, 0.0, variation_deg=-2.0),
    "buoy": lambda line: parse_buoy(line, 0.0),
    "thrusters": lambda line: parse_pzths(line, 0.0),
    "thruster_controller": parse_pzthr,
}

_TAU = 2.0 * math.pi
_KN = 1852.0 / 3600.0


def _bad(x: float | None, lo: float, hi: float) -> bool:
    return x is not None and not (math.isfinite(x) and lo <= x <= hi)


def implausible(m: Any) -> str | None:
    """The first value of a bus message outside its physical range, or None.

    Written from the physics, independently of the parsers' own limits:
    angles in [0, 2π) (heading, course) or ±π/2 (pitch) / ±π (roll),
    latitude ±90°, longitude ±180°, speed ≤ 100 kn, rate of turn ≤ 60 °/s,
    HDOP and GST deviations ≥ 0, satellites 0..99, dates 1980..2100,
    thruster commands ±100, currents ≥ 0, battery 0..100 V.
    """
    checks: list[tuple[str, float | None, float, float]] = []
    if isinstance(m, GpsFix):
        checks = [("lat", m.lat_deg, -90, 90), ("lon", m.lon_deg, -180, 180),
                  ("hdop", m.hdop, 0, 100), ("sats", m.num_sats, 0, 99),
                  ("alt", m.alt_m, -1000, 10000), ("age", m.age_s, 0, 1e4),
                  ("utc", m.utc_s, 0, 86401)]
    elif isinstance(m, GpsVelocity):
        checks = [("sog", m.sog_mps, 0, 100 * _KN), ("cog", m.cog_rad, 0, _TAU - 1e-12)]
    elif isinstance(m, GpsErrorStats):
        checks = [("std_lat", m.std_lat_m, 0, 1e5), ("std_lon", m.std_lon_m, 0, 1e5),
                  ("std_alt", m.std_alt_m, 0, 1e5), ("rms", m.rms_m, 0, 1e7)]
    elif isinstance(m, GpsTime):
        checks = [("epoch", m.utc_epoch_s, 315532800.0, 4102444800.0)]  # 1980..2100
    elif isinstance(m, Heading):
        checks = [("heading", m.heading_rad, 0, _TAU - 1e-12), ("raw", m.raw_deg, 0, 360),
                  ("variation", m.variation_deg, -180, 180),
                  ("deviation", m.deviation_deg, -180, 180)]
    elif isinstance(m, RateOfTurn):
        checks = [("rot", m.rate_rps, -math.radians(60), math.radians(60))]
    elif isinstance(m, Attitude):
        checks = [("pitch", m.pitch_rad, -math.pi / 2, math.pi / 2),
                  ("roll", m.roll_rad, -math.pi, math.pi)]
    elif isinstance(m, ThrusterStatus):
        checks = [("u1", m.u1, -100, 100), ("u2", m.u2, -100, 100),
                  ("amps1", m.amps1, 0, 1000), ("amps2", m.amps2, 0, 1000),
                  ("rpm1", m.rpm1, -1e5, 1e5), ("rpm2", m.rpm2, -1e5, 1e5)]
    elif isinstance(m, AcousticEvent):
        checks = [("epoch", m.utc_epoch_s, 315532800.0, 4102444800.0),
                  ("beacon", m.beacon, 0, 9999), ("snr", m.snr_db, -60, 140)]
    elif isinstance(m, BuoyStatus):
        checks = [("epoch", m.utc_epoch_s, 315532800.0, 4102444800.0),
                  ("battery", m.battery_v, 0, 100), ("fault", m.fault_code, 0, 9999)]
        if not (math.isnan(m.lat_deg) and math.isnan(m.lon_deg)):
            checks += [("lat", m.lat_deg, -90, 90), ("lon", m.lon_deg, -180, 180)]
    elif isinstance(m, tuple):  # parse_pzthr
        checks = [("u1", m[0], -100, 100), ("u2", m[1], -100, 100)]
    for name, x, lo, hi in checks:
        if _bad(x, lo, hi):
            return f"{type(m).__name__}.{name}={x!r}"
    return None


#: one valid sentence of each type the drivers read, by driver path
VALID: dict[str, list[str]] = {
    "gps": [
        "GNGGA,120000.00,4807.038,N,01131.324,E,4,14,0.7,5.0,M,46.9,M,1.0,0000",
        "GNRMC,120000.00,A,4807.038,N,01131.324,E,1.944,12.34,010626,2.0,E,R,S",
        "GNGLL,4807.038,N,01131.324,E,120000.00,A,D",
        "GNGNS,120000.00,4807.038,N,01131.324,E,DD,14,0.7,5.0,46.9,1.0,0000,S",
        "GNVTG,12.34,T,10.0,M,1.944,N,3.600,K,R",
        "GNGST,120000.00,0.015,0.02,0.01,12.0,0.015,0.015,0.030",
        "GNZDA,120000.00,01,06,2026,00,00",
        "GNHDT,123.4,T",
        "GNTHS,123.4,A",
    ],
    "compass": [
        "HCHDG,98.3,1.0,E,2.0,W", "HCHDM,218.6,M", "TIROT,-12.34,A",
        "YXXDR,A,0.4,D,PTCH,A,-1.2,D,ROLL",
    ],
    "buoy": [
        "PZBAE,101502.123456,010626,I,2,18.5",
        "PZBST,100001.00,010626,4111.100000,N,00842.300000,W,12.60,0",
    ],
    "thrusters": ["PZTHS,12.5,-3.0,1500,-700,3.20,1.05"],
    "thruster_controller": ["PZTHR,12.5,-3.0"],
}

_ANGLE = ["360.5", "400", "720.5", "999999", "-0.5", "-360"]
_TIME = ["240000.00", "236000.00", "235961.00", "999999.99"]
#: per sentence type, data field index → out-of-range values (checksum-valid,
#: well-formed numbers or dates that no instrument can produce)
OUT_OF_RANGE: dict[str, dict[int, list[str]]] = {
    "GGA": {0: _TIME, 1: ["9000.001", "9959.999"], 3: ["18000.001", "35959.9"],
            5: ["10", "99"], 6: ["100", "-1"], 7: ["-5", "-0.1", "100.0", "999.9"],
            8: ["-1000.1", "99999", "1000000"], 10: ["-200.5", "250"], 12: ["-1", "10000"],
            13: ["4096", "-1"]},
    "RMC": {0: _TIME, 2: ["9000.001"], 4: ["18000.001"], 6: ["99999", "-0.1", "100.1"],
            7: [*_ANGLE, "191194"], 8: ["320126", "290223", "001226", "011326"],
            9: ["180.1", "-3"]},
    "GLL": {0: ["9000.001"], 2: ["18000.001"], 4: _TIME},
    "GNS": {0: _TIME, 1: ["9000.001"], 3: ["18000.001"], 6: ["100", "-1"],
            7: ["-5", "100.0"], 8: ["99999", "-5000"], 9: ["250"], 10: ["-1", "10000"],
            11: ["4096"]},
    "VTG": {0: _ANGLE, 2: _ANGLE, 4: ["99999", "-1", "100.5"], 6: ["-1", "185.3", "99999"]},
    "GST": {0: _TIME, 1: ["-1", "20000000"], 2: ["-0.1", "200000"], 3: ["-0.1"],
            4: ["361", "-1"], 5: ["-0.01", "100001"], 6: ["-0.01"], 7: ["-0.01", "1e9"]},
    "ZDA": {0: _TIME, 1: ["0", "32"], 2: ["0", "13"], 3: ["9999", "1979", "2100", "0"],
            4: ["14", "-14"], 5: ["60", "-1"]},
    "HDT": {0: _ANGLE},
    "THS": {0: _ANGLE},
    "HDG": {0: _ANGLE, 1: ["180.5", "-1", "999"], 3: ["180.5", "-2", "999"]},
    "HDM": {0: _ANGLE},
    "ROT": {0: ["1000000", "-1000000", "3600.1", "-99999"]},
    "XDR": {1: ["90.1", "171", "-95", "999"], 5: ["180.1", "-200", "720"]},
    "PZBAE": {0: ["251502.123456", "106002.123456", "101561.000000"],
              1: ["320126", "290223", "011326", "000126"], 3: ["-1", "10000"],
              4: ["140.1", "-60.1", "99999"]},
    "PZBST": {0: ["240000.00", "236000.00"], 1: ["320126"], 2: ["9100.000000"],
              4: ["18000.000001"], 6: ["-1", "100.01", "99999"], 7: ["-1", "10000"]},
    "PZTHS": {0: ["100.1", "-150"], 1: ["100.05", "-999"], 2: ["100001", "-100001"],
              3: ["-100001"], 4: ["-0.5", "1000.1"], 5: ["-3", "99999"]},
    "PZTHR": {0: ["100.1", "-100.1", "99999"], 1: ["-100.05", "1000"]},
}


def out_of_range_set() -> list[tuple[str, str, int, str]]:
    """(driver path, framed line, field index, value) for every out-of-range case."""
    out = []
    for path, bodies in VALID.items():
        for body in bodies:
            address, *fields = body.split(",")
            stype = address if address.startswith("P") else address[2:]
            for k, values in OUT_OF_RANGE[stype].items():
                for v in values:
                    f = list(fields)
                    f[k] = v
                    line = _frame(",".join([address, *f])).decode()
                    out.append((path, line, k, v))
    return out


def run_out_of_range(paths: dict[str, ParserFn] | None = None) -> dict[str, Any]:
    """Feed the out-of-range set through the driver paths; the valid sentences
    first (all must be accepted, else the set proves nothing)."""
    paths = PATHS if paths is None else paths
    valid_refused = []
    for path, bodies in VALID.items():
        for body in bodies:
            try:
                paths[path](_frame(body).decode())
            except NmeaError as exc:
                valid_refused.append(f"{body}: {exc}")
    accepted: list[str] = []
    reasons: Counter[str] = Counter()
    by_type: Counter[str] = Counter()
    cases = out_of_range_set()
    for path, line, _k, _v in cases:
        stype = line[1:6] if line[1] == "P" else line[3:6]
        try:
            paths[path](line)
        except NmeaError as exc:
            reasons[exc.reason] += 1
            continue
        except Exception as exc:  # counted as an escape by the main run's standard
            reasons[f"escaped:{type(exc).__name__}"] += 1
            continue
        accepted.append(line)
        by_type[stype] += 1
    return {"sentences": len(cases), "accepted": len(accepted),
            "accepted_by_type": dict(sorted(by_type.items())),
            "rejections": dict(sorted(reasons.items())),
            "valid_refused": valid_refused, "examples": accepted[:8]}


def run(lines: int, seed: int, progress: bool = False,
        paths: dict[str, ParserFn] | None = None) -> dict[str, Any]:
    """Fuzz ``lines`` mutated lines through every driver path (or ``paths``:
    name → parser of one framed line); return the figures."""
    paths = PATHS if paths is None else paths
    rng = random.Random(seed)
    pools = load_corpus(seed)
    names = list(POOL_WEIGHTS)
    weights = [POOL_WEIGHTS[n] for n in names]
    mut = Mutator([x for p in pools.values() for x in p], rng)
    framers = {name: NmeaFramer() for name in paths}
    escaped: list[dict[str, str]] = []
    bad_used: list[dict[str, str]] = []
    implausible_used: list[dict[str, str]] = []
    reasons: Counter[str] = Counter()
    accepted: Counter[str] = Counter()
    frames = valid_frames = 0
    w0 = time.perf_counter()
    for i in range(lines):
        pool = pools[rng.choices(names, weights)[0]]
        data = mut.mutate(rng.choice(pool)) + b"\r\n"
        for name, parse in paths.items():
            for frame in framers[name].feed(data):
                frames += 1
                ok = valid_checksum(frame)
                valid_frames += ok
                try:
                    result = parse(frame)
                except NmeaError as exc:
                    reasons[f"{name}:{exc.reason}"] += 1
                    continue
                except Exception as exc:  # the bug this bench looks for
                    escaped.append({"path": name, "line": repr(frame),
                                    "error": f"{type(exc).__name__}: {exc}"})
                    continue
                accepted[name] += 1
                if not ok:
                    bad_used.append({"path": name, "line": repr(frame)})
                msgs = result if isinstance(result, list) else [result]
                for m in msgs:
                    why = implausible(m)
                    if why is not None:
                        implausible_used.append({"path": name, "line": repr(frame),
                                                 "value": why})
        if progress and i % 20000 == 0 and i:
            print(f"fuzz: {i} lines, {len(escaped)} escaped, {len(bad_used)} bad used",
                  file=sys.stderr)
    wall = time.perf_counter() - w0
    discarded = {name: f.bytes_discarded for name, f in framers.items()}
    return {
        "bench": "fuzz",
        "seed": seed,
        "lines": lines,
        "corpus_lines": {k: len(v) for k, v in pools.items()},
        "frames_per_path": frames // len(paths),
        "frames_with_valid_checksum": valid_frames // len(paths),
        "accepted": dict(accepted),
        "escaped_exceptions": len(escaped),
        "bad_checksum_used": len(bad_used),
        "implausible_used": len(implausible_used),
        "bytes_discarded": discarded,
        "rejections": dict(sorted(reasons.items())),
        "mutations": dict(sorted(mut.used.items())),
        "wall_s": round(wall, 2),
        "examples": {"escaped": escaped[:5], "bad_checksum_used": bad_used[:5],
                     "implausible_used": implausible_used[:5]},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lines", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    r = run(args.lines, args.seed, progress=True)
    print(f"fuzz: {r['lines']} mutated lines, {r['frames_per_path']} frames per path "
          f"({r['frames_with_valid_checksum']} with a valid checksum), accepted "
          f"{r['accepted']}, {r['escaped_exceptions']} escaped exceptions, "
          f"{r['bad_checksum_used']} bad-checksum sentences used, "
          f"{r['implausible_used']} implausible values used, {r['wall_s']} s",
          file=sys.stderr)
    for kind, items in r["examples"].items():
        for x in items:
            print(f"  {kind}: {x}", file=sys.stderr)
    oor = run_out_of_range()
    print(f"fuzz: out-of-range set: {oor['sentences']} checksum-valid sentences, "
          f"{oor['accepted']} accepted {oor['accepted_by_type']}", file=sys.stderr)
    for x in oor["examples"]:
        print(f"  out_of_range accepted: {x}", file=sys.stderr)
    r = {k: v for k, v in r.items() if k != "examples"}
    r["out_of_range"] = {k: v for k, v in oor.items() if k != "examples"}
    print(json.dumps(r))
    bad = (r["escaped_exceptions"] or r["bad_checksum_used"] or r["implausible_used"]
           or oor["accepted"] or oor["valid_refused"])
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
