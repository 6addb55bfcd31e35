"""Fault injection for the simulated devices: the schedule (scenario schema) and
what each fault does to a device's bytes.

A scenario lists its faults as an array of tables (``[[faults]]``); each one
acts on one device from ``at_s`` (seconds after the run starts) for
``duration_s``::

    [[faults]]
    kind = "unplug"          # the port vanishes and comes back at the same path
    device = "gps"
    at_s = 40.0
    duration_s = 2.0

    [[faults]]
    kind = "noise"           # random bytes between the sentences
    device = "compass"
    at_s = 60.0
    duration_s = 3.0
    bytes_per_s = 3000.0
    binary = true

========================  ================================================================
``unplug``                the device's pseudo-terminal is closed and its link removed;
                          after ``duration_s`` a new one appears at the same link path
``noise``                 ``bytes_per_s`` random bytes (``binary``: any value; else
                          NMEA-looking ASCII with ``$``, ``*``, commas, CR LF) mixed in
``truncate``              a ``fraction`` of sentences is cut short (no CR LF, rest lost)
``bad_checksum``          a ``fraction`` of sentences carries a wrong ``*hh``
``split``                 every write is cut into pieces of 1..``chunk_max_bytes`` bytes,
                          ``chunk_gap_s`` apart
``silence``               the device sends nothing (the port stays open)
``fix``                   GPS only: the receiver's fix becomes ``fix`` (rtk_float, single,
                          none, ...); after ``duration_s`` the previous mode returns
                          (``duration_s = 0``: for the rest of the run)
``freeze``                the device repeats, byte for byte, what it sent when the fault
                          began (a compass stuck on one heading; checksums stay valid)
========================  ================================================================

The dataclass follows the configuration conventions of
``zarco_core.config`` (``spec`` fields with unit, doc and range; a
``validate`` for checks across fields).  :class:`FaultPlan` is pure and
seeded: the simulator asks it, at each write, what the device really sends.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from drivers.sim.params import FIX_MODES
from zarco_core.config import spec

FAULT_KINDS = ("unplug", "noise", "truncate", "bad_checksum", "split", "silence", "fix",
               "freeze")
FAULT_DEVICES = ("gps", "compass", "thrusters", "buoy")
#: NMEA-looking noise (a cable picking up another talker, a wrong baud rate)
ASCII_NOISE = b"$$GPNM,,,,..**0123456789ABCDEF\r\n"


@dataclass(slots=True)
class FaultSpec:
    """One scheduled fault (an element of the scenario's ``[[faults]]``)."""

    kind: str = spec("unplug", "", "what goes wrong", choices=list(FAULT_KINDS))
    device: str = spec("gps", "", "the device it happens to", choices=list(FAULT_DEVICES))
    at_s: float = spec(0.0, "s", "start, seconds after the run starts", min=0.0, max=1e6)
    duration_s: float = spec(1.0, "s", "how long it lasts (fix: 0 = for the rest of the run)",
                             min=0.0, max=1e6)
    fraction: float = spec(1.0, "", "share of sentences hit (truncate, bad_checksum)",
                           min=0.0, max=1.0)
    bytes_per_s: float = spec(2000.0, "B/s", "noise rate (noise)", min=1.0, max=1e6)
    binary: bool = spec(True, "", "noise of any byte value (else NMEA-looking ASCII)")
    chunk_max_bytes: int = spec(4, "B", "largest piece of a split write (split)", min=1,
                                max=1024)
    chunk_gap_s: float = spec(0.001, "s", "pause between the pieces of a split write (split)",
                              min=0.0, max=1.0)
    fix: str = spec("none", "", "GPS fix mode during the fault (fix)", choices=list(FIX_MODES))

    def validate(self) -> None:
        if self.kind == "fix" and self.device != "gps":
            raise ValueError(f"device: a fix fault is a GPS fault, got {self.device!r}")
        if self.kind != "fix" and self.duration_s <= 0.0:
            raise ValueError(f"duration_s: a {self.kind} fault must last > 0 s")

    @property
    def end_s(self) -> float:
        """End of the fault (inf for a fix change that stays)."""
        if self.kind == "fix" and self.duration_s == 0.0:
            return float("inf")
        return self.at_s + self.duration_s

    def active(self, t_s: float) -> bool:
        return self.at_s <= t_s < self.end_s

    @property
    def label(self) -> str:
        extra = f" → {self.fix}" if self.kind == "fix" else ""
        return f"{self.device} {self.kind}{extra} at {self.at_s:g} s for {self.duration_s:g} s"


def _sentences(data: bytes) -> list[bytes]:
    """Split a device write into its sentences, each with its CR LF."""
    parts = data.split(b"\r\n")
    out = [p + b"\r\n" for p in parts[:-1]]
    if parts[-1]:
        out.append(parts[-1])
    return out


class FaultPlan:
    """What each device really sends, given the fault schedule (pure, seeded).

    One random stream per device (``random.Random(f"{seed}:{device}")``), so
    a fault on one device never changes another's bytes.
    """

    def __init__(self, faults: list[FaultSpec], seed: int = 0) -> None:
        self.faults = sorted(faults, key=lambda f: f.at_s)
        self._rng = {d: random.Random(f"{seed}:{d}") for d in FAULT_DEVICES}
        self._frozen: dict[str, bytes | None] = dict.fromkeys(FAULT_DEVICES)

    def active(self, device: str, kind: str, t_s: float) -> FaultSpec | None:
        for f in self.faults:
            if f.device == device and f.kind == kind and f.active(t_s):
                return f
        return None

    def any_active(self, t_s: float, device: str | None = None) -> bool:
        return any(f.active(t_s) and (device is None or f.device == device)
                   for f in self.faults)

    def plugged(self, device: str, t_s: float) -> bool:
        return self.active(device, "unplug", t_s) is None

    def fix_mode(self, t_s: float, default: str) -> str:
        """GPS fix mode at ``t_s``: the latest active fix fault's, else ``default``."""
        mode = default
        for f in self.faults:
            if f.kind == "fix" and f.active(t_s):
                mode = f.fix
        return mode

    def edges(self) -> list[float]:
        """Every time at which some fault starts or ends (sorted, finite)."""
        ts = {f.at_s for f in self.faults} | {f.end_s for f in self.faults}
        return sorted(t for t in ts if t != float("inf"))

    def windows(self) -> list[tuple[float, float, str]]:
        return [(f.at_s, f.end_s, f.label) for f in self.faults]

    def shape(self, device: str, t_s: float, data: bytes) -> tuple[list[bytes], float]:
        """The writes (and the pause between them, s) that replace ``data`` at ``t_s``."""
        if self.active(device, "silence", t_s) is not None:
            return [], 0.0
        rng = self._rng[device]
        if self.active(device, "freeze", t_s) is not None:
            if self._frozen[device] is None:
                self._frozen[device] = data
            data = self._frozen[device] or data
        else:
            self._frozen[device] = None
        tr = self.active(device, "truncate", t_s)
        bad = self.active(device, "bad_checksum", t_s)
        if tr is not None or bad is not None:
            out = []
            for s in _sentences(data):
                if bad is not None and rng.random() < bad.fraction:
                    star = s.rfind(b"*")
                    if 0 < star <= len(s) - 3:
                        good = int(s[star + 1:star + 3], 16)
                        s = s[:star + 1] + b"%02X" % (good ^ rng.randint(1, 255)) + s[star + 3:]
                if tr is not None and rng.random() < tr.fraction and len(s) > 3:
                    s = s[:rng.randint(1, len(s) - 3)]
                out.append(s)
            data = b"".join(out)
        sp = self.active(device, "split", t_s)
        if sp is not None and data:
            chunks = []
            i = 0
            while i < len(data):
                n = rng.randint(1, sp.chunk_max_bytes)
                chunks.append(data[i:i + n])
                i += n
            return chunks, sp.chunk_gap_s
        return ([data] if data else []), 0.0

    def noise(self, device: str, t0_s: float, t1_s: float) -> bytes:
        """Noise bytes the device's line picks up over [t0, t1)."""
        out = b""
        rng = self._rng[device]
        for f in self.faults:
            if f.device != device or f.kind != "noise":
                continue
            overlap = min(t1_s, f.end_s) - max(t0_s, f.at_s)
            if overlap <= 0.0:
                continue
            n = int(f.bytes_per_s * overlap + rng.random())
            if f.binary:
                out += rng.randbytes(n)
            else:
                out += bytes(rng.choice(ASCII_NOISE) for _ in range(n))
        return out
