"""Fuzz the NMEA driver paths with seeded mutations of real receivers' lines.

    python tests/bench/fuzz.py [--lines 100000] [--seed 1]

Seed corpus: every sentence of ``tests/data/gpsd-logs/*.log`` (GPSD's real
captures: GGA, RMC, VTG, GST, ZDA, HDT, HDM, ROT, XDR, GSV, ...) plus the
sentences the project's own devices speak and no capture holds: the
simulated compass's HDG/ROT/XDR and ``$PZTHR``/``$PZTHS`` of the thruster
controller (DESIGN.md §7).

Each mutated line is one to three of: bit flips, truncation, insertion of
random bytes (printable or binary), deletion, field swap / duplication /
deletion, a field replaced by a nasty value (``nan``, ``1e9``, ``-``,
a 40-digit number, ...), splicing with another line, lower-case checksum,
missing checksum.  With probability ½ the checksum is then recomputed over
the mutated content, so that the field parsers, not only the checksum
check, see the damage.

Every mutated line (plus CR LF) goes through each driver path exactly as the
drivers run it: :class:`~drivers.nmea.NmeaFramer` then ``parse_gps`` (GPS
driver), ``parse_compass`` (compass driver), ``parse_pzths`` (thruster
driver) and ``parse_pzthr`` (the thruster controller's side of the link).
Counted:

* ``escaped_exceptions`` — anything but ``NmeaError`` out of a parser (must be 0);
* ``bad_checksum_used`` — a sentence accepted although an independent check
  (last ``*``, exactly two hex digits, XOR of the bytes between the start
  character and that ``*``) says its checksum is bad or missing (must be 0).

Ends by printing one JSON line of its figures.
"""

from __future__ import annotations

import argparse
import json
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

from drivers.compass_parser import parse_compass  # noqa: E402
from drivers.gps_parser import parse_gps  # noqa: E402
from drivers.nmea import NmeaError, NmeaFramer  # noqa: E402
from drivers.thruster_protocol import parse_pzthr, parse_pzths  # noqa: E402

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
    pools: dict[str, list[bytes]] = {"gps": [], "compass": [], "thrusters": []}
    for log in sorted(LOGS.glob("*.log")):
        pool = pools["compass" if log.name == "pypilot.log" else "gps"]
        for raw in log.read_bytes().splitlines():
            if raw.startswith((b"$", b"!")):
                pool.append(raw.rstrip(b"\r\n"))
    for s in OWN_SENTENCES:
        body = s[1:-1]
        pool = "thrusters" if body.startswith("PZ") else (
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
    return pools


#: share of seed lines drawn from each pool
POOL_WEIGHTS = {"gps": 0.5, "compass": 0.25, "thrusters": 0.25}


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
    "thrusters": lambda line: parse_pzths(line, 0.0),
    "thruster_controller": parse_pzthr,
}


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
                    parse(frame)
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
        "bytes_discarded": discarded,
        "rejections": dict(sorted(reasons.items())),
        "mutations": dict(sorted(mut.used.items())),
        "wall_s": round(wall, 2),
        "examples": {"escaped": escaped[:5], "bad_checksum_used": bad_used[:5]},
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
          f"{r['bad_checksum_used']} bad-checksum sentences used, {r['wall_s']} s",
          file=sys.stderr)
    for kind, items in r["examples"].items():
        for x in items:
            print(f"  {kind}: {x}", file=sys.stderr)
    print(json.dumps({k: v for k, v in r.items() if k != "examples"}))
    sys.exit(1 if r["escaped_exceptions"] or r["bad_checksum_used"] else 0)


if __name__ == "__main__":
    main()
