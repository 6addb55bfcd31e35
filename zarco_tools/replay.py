"""``zarco replay LOG --port PATH [--rate N]``: a recorded capture back into a serial port.

The tool for a capture from the boat (or GPSD's regression logs): it writes
the capture's sentences into a serial port or pseudo-terminal at the pace
they were recorded, so the runtime (or any NMEA reader) sees them as from the
device.

Pacing comes from the capture's own clocks: the UTC time of day of every
GGA, RMC, ZDA (also GNS, GLL) sentence with a valid checksum.  Each line is
sent at the time of the last timed sentence before it (a receiver sends an
epoch's sentences back to back; lines before the first time go out with
it).  Times that run backwards are not waited for; midnight is unwrapped;
silences longer than ``max_gap_s`` are shortened to it.  A capture without
any time goes out at ``line_rate_hz`` lines per second.  ``rate`` N plays N
times faster; 0 sends everything as fast as the port takes it.

Lines starting with ``#`` and blank lines are not sent; every line is sent
with a CR LF ending, as NMEA 0183 has it.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import re
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import IO, Any

from drivers.nmea import NmeaError, split_checked
from zarco_core.paths import PathError, readable_file
from zarco_tools.status_line import TtyLine

#: sentence type → index of its UTC time field
TIME_FIELD = {"GGA": 0, "RMC": 0, "ZDA": 0, "GNS": 0, "GLL": 4}
_TIME_RE = re.compile(r"(\d\d)(\d\d)(\d\d(?:\.\d+)?)")
DAY_S = 86400.0


def sentence_time(line: bytes) -> float | None:
    """UTC seconds of the day carried by a checked GGA/RMC/ZDA/GNS/GLL, else None."""
    try:
        address, fields = split_checked(line.decode("ascii"))
    except (UnicodeDecodeError, NmeaError):
        return None
    idx = TIME_FIELD.get(address[2:]) if len(address) == 5 else None
    if idx is None or len(fields) <= idx:
        return None
    m = _TIME_RE.fullmatch(fields[idx])
    if m is None:
        return None
    hh, mm, ss = int(m[1]), int(m[2]), float(m[3])
    if hh > 23 or mm > 59 or ss >= 61.0:
        return None
    return hh * 3600 + mm * 60 + ss


@dataclass(slots=True)
class Schedule:
    """Lines to send (with CR LF) and their send times (s after the start, recorded pace)."""

    lines: list[bytes]
    offsets_s: list[float]
    timed: bool  # paced by the capture's clocks (else by the line rate)

    @property
    def duration_s(self) -> float:
        return self.offsets_s[-1] if self.offsets_s else 0.0


def build_schedule(raw_lines: Iterable[bytes], line_rate_hz: float = 10.0,
                   max_gap_s: float | None = 10.0) -> Schedule:
    """Assign every NMEA line of a capture its send time at the recorded pace."""
    lines: list[bytes] = []
    times: list[float | None] = []
    for raw in raw_lines:
        body = raw.rstrip(b"\r\n")
        if not body.strip() or body.startswith(b"#"):
            continue
        lines.append(body + b"\r\n")
        times.append(sentence_time(body))
    if not any(t is not None for t in times):
        step = 0.0 if line_rate_hz <= 0 else 1.0 / line_rate_hz
        return Schedule(lines, [i * step for i in range(len(lines))], False)
    offsets: list[float] = []
    last_raw: float | None = None
    day = 0.0
    now = 0.0  # current send offset
    last_t: float | None = None  # recorded time the current offset corresponds to
    for t in times:
        if t is not None:
            if last_raw is not None and t < last_raw - DAY_S / 2:
                day += DAY_S  # past midnight
            last_raw = t
            tu = t + day
            if last_t is None:
                last_t = tu  # the first time: lines before it go out with it
            gap = tu - last_t
            if gap > 0:
                if max_gap_s and gap > max_gap_s:
                    gap = max_gap_s
                now += gap
                last_t = tu
            elif gap < -1.0:
                last_t = tu  # the capture's clock jumped back: carry on from here
        offsets.append(now)
    return Schedule(lines, offsets, True)


@dataclass(slots=True)
class ReplayStats:
    lines: int = 0
    bytes: int = 0
    wall_s: float = 0.0
    late_max_s: float = 0.0  # worst lateness of a write against its schedule


class Progress:
    """Progress on stderr: rewritten in place on a terminal, every 5 s otherwise."""

    def __init__(self, total_lines: int, duration_s: float, stream: Any = None) -> None:
        self.total = total_lines
        self.duration_s = duration_s
        self.line = TtyLine(stream)

    def __call__(self, done: int, rec_s: float, force: bool = False) -> None:
        if not self.line.due(force):
            return
        pct = 100.0 * done / self.total if self.total else 100.0
        self.line.write(f"replay: {done}/{self.total} lines ({pct:5.1f} %)  "
                        f"recorded time {rec_s:7.1f}/{self.duration_s:.1f} s")

    def close(self) -> None:
        self.line.end("\n")


def play(schedule: Schedule, write: Callable[[bytes], object], rate: float = 1.0,
         loops: int = 1, progress: Callable[[int, float], None] | None = None,
         clock: Callable[[], float] = time.monotonic,
         sleep: Callable[[float], None] = time.sleep) -> ReplayStats:
    """Write the schedule's lines at ``rate`` × the recorded pace (0: no waiting).

    Lines due at the same time are written together, in order.  ``loops`` 0
    repeats forever (until KeyboardInterrupt, which ends the replay cleanly).
    """
    st = ReplayStats()
    n = len(schedule.lines)
    if n == 0:
        return st
    offs = schedule.offsets_s
    # a loop restarts one typical interval after its last line
    diffs = sorted(b - a for a, b in itertools.pairwise(offs) if b > a)
    period = diffs[len(diffs) // 2] if diffs else 0.1
    t0 = clock()
    base = 0.0
    k = 0
    try:
        while loops == 0 or k < loops:
            i = 0
            while i < n:
                due = offs[i]
                j = i + 1
                while j < n and offs[j] == due:
                    j += 1
                if rate > 0:
                    target = t0 + (base + due) / rate
                    delay = target - clock()
                    if delay > 0:
                        sleep(delay)
                    st.late_max_s = max(st.late_max_s, clock() - target)
                chunk = b"".join(schedule.lines[i:j])
                write(chunk)
                st.lines += j - i
                st.bytes += len(chunk)
                if progress is not None:
                    progress(st.lines, due)
                i = j
            base += schedule.duration_s + period
            k += 1
    except KeyboardInterrupt:
        pass
    st.wall_s = clock() - t0
    return st


def open_port(path: str, baudrate: int) -> Any:
    """The port as a pyserial ``Serial`` (works for pseudo-terminals too)."""
    import serial

    return serial.Serial(path, baudrate=baudrate, write_timeout=None)


def main_replay(args: Any, err: IO[str] | None = None) -> int:
    """``zarco replay``; 0 on success, 1 if the port cannot be opened or written;
    a capture or a port path that does not exist raises PathError (exit 2)."""
    err = err or sys.stderr
    if args.log != "-":
        readable_file(args.log)
    if not os.path.exists(args.port):
        raise PathError(args.port, "no such file or directory (the serial port or "
                        "pseudo-terminal to write to)", "--port")
    try:
        if args.log == "-":
            raw = sys.stdin.buffer.read()
        else:
            with open(args.log, "rb") as fh:
                raw = fh.read()
    except OSError as exc:
        err.write(f"zarco replay: {args.log}: {exc.strerror or exc}\n")
        return 1
    sched = build_schedule(raw.splitlines(), args.line_rate, args.max_gap or None)
    if not sched.lines:
        err.write(f"zarco replay: {args.log}: no NMEA lines\n")
        return 1
    try:
        port = open_port(args.port, args.baudrate)
    except (OSError, ValueError) as exc:  # serial.SerialException is an OSError
        err.write(f"zarco replay: {args.port}: {exc}\n")
        return 1
    pace = (f"{args.rate:g}× the recorded pace" if args.rate > 0 else "as fast as possible")
    how = "capture's times" if sched.timed else f"{args.line_rate:g} lines/s (no times)"
    if not args.quiet:
        err.write(f"replay: {len(sched.lines)} lines, {sched.duration_s:.1f} s recorded "
                  f"({how}), {pace}, into {args.port}\n")
    prog = None if args.quiet else Progress(len(sched.lines) * max(1, args.loop),
                                            sched.duration_s, err)
    try:
        st = play(sched, port.write, args.rate, args.loop,
                  (lambda d, t: prog(d, t)) if prog else None)
        with contextlib.suppress(Exception):
            port.flush()
    except OSError as exc:
        err.write(f"\nzarco replay: {args.port}: write failed: {exc}\n")
        return 1
    finally:
        port.close()
    if prog is not None:
        prog(st.lines, sched.duration_s, force=True)
        prog.close()
        err.write(f"replay: sent {st.lines} lines, {st.bytes} bytes in {st.wall_s:.2f} s "
                  f"(worst lateness {1000 * st.late_max_s:.1f} ms)\n")
    return 0
