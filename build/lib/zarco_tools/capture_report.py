"""What the navigation EKF estimates from a recorded NMEA capture (issue 5).

``zarco navreport LOG [LOG ...]`` and :func:`capture_report`: a capture (GPSD's
regression logs, or one from the boat) goes through the drivers' own path —
:class:`drivers.nmea.NmeaFramer`, then :func:`~drivers.gps_parser.parse_gps`
or, for the sentence types only a compass sends (HDG, HDM, ROT, XDR),
:func:`~drivers.compass_parser.parse_compass` — into
:class:`~zarco_runtime.navigation.ekf.EkfNavigator` with default
:class:`~zarco_runtime.navigation.ekf_config.EkfSettings`, and the report says
what it estimated at the end of the capture.

Input: lines starting with ``#`` (GPSD's comments) and blank lines are
skipped.  A sentence no parser takes (bad checksum, empty heading, VTG mode N,
an unsupported type, ...) is *refused*: counted by its reason (the drivers'
counter keys: ``empty``, ``invalid``, ``checksum``, ``unsupported``, ...) and by
its sentence type, never raised.  Bytes the framer throws away count as one
``framing`` refusal per input line.

Timing: captures carry no arrival times.  When the capture has UTC times of
its own (a checked GGA, RMC, ZDA, also GNS/GLL: :func:`zarco_tools.replay.
sentence_time`), every sentence is timed by the last of them (s after the first
one, midnight unwrapped), plus 1 ms per sentence so that the sentences of one
epoch keep their order; a clock that runs back by more than 1 s is followed
from where it is, without going back in time.  A capture without any UTC is
timed at ``line_rate_hz`` sentences per second from t = 0.  Refused sentences
take their time slot too.  ``t`` in the report is that clock (s).

Magnetic headings (HDG, HDM): an HDG that carries its own variation is made
true by the parser with it; other magnetic headings are made true with
``variation_deg`` (east positive) when given; otherwise they reach the EKF
magnetic, i.e. corrected by 0°, and the report says so
(``variation.magnetic_uncorrected``).  The EKF itself gets no variation (each
heading is corrected once, here).

Local frame: NED (x north, y east, m) about the first GpsFix with a fix
(quality better than none and a position), whether or not the filter then
fuses it; a capture without any fix uses lat 0°, lon 0° (and reports no
position).

Errors: an exception raised by the EKF on a message (or when asked for its
state) is caught, counted in ``errors`` (with the first few in
``error_samples``) and the capture carries on, so a bad capture never stops
the tool.  The CLI exits 1 when any capture had one.
"""

from __future__ import annotations

import json
import math
import sys
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from drivers.compass_parser import heading_from_magnetic, parse_compass
from drivers.gps_parser import parse_gps
from drivers.nmea import NmeaError, NmeaFramer, sentence_type
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    FixQuality,
    GpsFix,
    Heading,
)
from zarco_runtime.navigation.ekf import KIND_NAMES, EkfNavigator
from zarco_runtime.navigation.ekf_config import EkfSettings
from zarco_tools.decode import is_compass_type
from zarco_tools.replay import sentence_time

#: time added per sentence in a UTC-timed capture (s): keeps an epoch's order
SENTENCE_STEP_S = 1e-3
#: a capture clock running back by more than this (s) is followed from there
CLOCK_BACK_S = 1.0
DAY_S = 86400.0
#: how many EKF exceptions are kept as text in the report
ERROR_SAMPLES = 5


def parse_sentence(line: str, t: float, variation_deg: float | None = None) -> list[Any]:
    """One framed sentence received at ``t`` (s) → bus messages, or ``NmeaError``.

    Routed as ``zarco decode`` routes it (:func:`zarco_tools.decode.is_compass_type`):
    the types only a compass sends to :func:`parse_compass` (source ``compass``),
    everything else to :func:`parse_gps` (source ``gps``: HDT/THS are the
    receiver's true heading).  ``variation_deg`` (east +) is given to the GPS
    parser only (a VTG with a magnetic track only): magnetic headings come back
    magnetic unless their HDG carries its own variation.
    """
    if is_compass_type(sentence_type(line)):
        return parse_compass(line, t, "compass", None)
    return parse_gps(line, t, "gps", variation_deg)


@dataclass(slots=True)
class Capture:
    """A capture framed, timed and parsed (see the module doc).

    ``messages``: bus messages in capture order, ``t`` on the capture's clock
    (s), magnetic headings already corrected where a variation is known;
    ``sentences``: framed sentences; ``refused`` / ``refused_kind``: refusals by
    reason and by sentence type; ``timed``: True when timed by the capture's UTC
    (else ``line_rate_hz``); ``headings``: how each heading reached the filter
    (``true``, ``variation_sentence``, ``variation_argument``, ``uncorrected``).
    """

    messages: list[Any] = field(default_factory=list)
    sentences: int = 0
    refused: Counter[str] = field(default_factory=Counter)
    refused_kind: Counter[str] = field(default_factory=Counter)
    timed: bool = False
    headings: Counter[str] = field(default_factory=Counter)
    #: the last variation applied to a heading (deg east +) and where it came from
    variation_deg: float | None = None
    variation_source: str = "none"


def _frame(raw_lines: Iterable[bytes], cap: Capture) -> list[str]:
    """Framed sentences of a capture; framing losses go to ``cap.refused``."""
    framer = NmeaFramer()
    out: list[str] = []
    for raw in raw_lines:
        body = raw.rstrip(b"\r\n")
        if not body.strip() or body.startswith(b"#"):
            continue
        lost = framer.bytes_discarded
        out.extend(framer.feed(body + b"\r\n"))
        if framer.bytes_discarded > lost:
            cap.refused["framing"] += 1
            cap.refused_kind["?"] += 1
    return out


def _correct_heading(m: Heading, variation_deg: float | None, cap: Capture) -> Heading:
    """Count how heading ``m`` is referenced; make a magnetic one true with
    ``variation_deg`` (east +) when that is known."""
    if m.true:
        if m.variation_deg is None:
            cap.headings["true"] += 1  # HDT / THS
        else:
            cap.headings["variation_sentence"] += 1  # HDG with its own variation
            cap.variation_deg, cap.variation_source = m.variation_deg, "sentence"
        return m
    if variation_deg is None:
        cap.headings["uncorrected"] += 1
        return m
    cap.headings["variation_argument"] += 1
    if cap.variation_source != "sentence":
        cap.variation_deg, cap.variation_source = variation_deg, "argument"
    return heading_from_magnetic(m.t, m.source, m.sentence, m.raw_deg, m.deviation_deg,
                                 variation_deg)


def read_capture(path: Path, variation_deg: float | None = None,
                 line_rate_hz: float = 5.0) -> Capture:
    """Frame, time and parse the capture at ``path`` (see the module doc).

    ``variation_deg``: magnetic variation (deg, east +) for magnetic headings
    that carry none; ``line_rate_hz``: sentences per second for a capture
    without UTC times.  Raises ``OSError`` if the file cannot be read and
    ``ValueError`` for a ``line_rate_hz`` that is not > 0; nothing for its
    content.
    """
    if not line_rate_hz > 0.0 or not math.isfinite(line_rate_hz):
        raise ValueError(f"line_rate_hz must be a finite number > 0, got {line_rate_hz}")
    cap = Capture()
    lines = _frame(Path(path).read_bytes().splitlines(), cap)
    utcs = [sentence_time(line.encode("ascii")) for line in lines]
    cap.timed = any(u is not None for u in utcs)
    cap.sentences = len(lines)
    t = 0.0
    utc0: float | None = None  # capture UTC (unwrapped) at t = 0
    last_utc: float | None = None
    day = 0.0
    for i, (line, utc) in enumerate(zip(lines, utcs, strict=True)):
        if not cap.timed:
            t = i / line_rate_hz
        else:
            t += SENTENCE_STEP_S
            if utc is not None:
                if last_utc is not None and utc < last_utc - DAY_S / 2:
                    day += DAY_S  # past midnight
                last_utc = utc
                utc += day
                if utc0 is None:
                    utc0 = utc - t
                if utc - utc0 < t - CLOCK_BACK_S:
                    utc0 = utc - t  # the capture's clock went back: carry on from here
                t = max(t, utc - utc0)
        try:
            msgs = parse_sentence(line, t, variation_deg)
        except NmeaError as exc:
            cap.refused[exc.reason] += 1
            cap.refused_kind[sentence_type(line)] += 1
            continue
        for m in msgs:
            cap.messages.append(_correct_heading(m, variation_deg, cap)
                                if isinstance(m, Heading) else m)
    return cap


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _r(x: float | None, nd: int) -> float | None:
    return None if x is None or not math.isfinite(x) else round(x, nd)


def capture_report(path: Path, variation_deg: float | None = None,
                   line_rate_hz: float = 5.0) -> dict[str, Any]:
    """Run the navigation EKF over the NMEA capture at ``path``; what it estimated.

    ``variation_deg``: magnetic variation (deg, east +) for magnetic headings
    without their own (HDG's variation wins); ``line_rate_hz``: sentences per
    second for a capture without UTC times.  Framing, timing, refusals, the
    local frame (origin: the first fix, else 0°, 0°) and error handling as in
    the module doc.  Raises ``OSError`` when the file cannot be read.

    Returns a JSON-ready dict (non-finite numbers as None):

    * ``file``, ``timing`` (``utc`` or ``line_rate``), ``sentences`` (framed),
      ``refused`` = {``total``, ``by_reason``, ``by_kind``} (kind = sentence
      type), ``messages`` (count by message class), ``fix_types`` (GpsFix count
      by fix label, ``none`` included);
    * ``origin`` = {``lat_deg``, ``lon_deg``, ``from``: ``first_fix`` | ``none``};
    * ``variation`` = {``deg`` (applied, 0 when none), ``source`` (``sentence``,
      ``argument``, ``none``), ``headings`` (count by how each heading was
      referenced: ``true``, ``variation_sentence``, ``variation_argument``,
      ``uncorrected``), ``magnetic_uncorrected`` (a magnetic heading reached the
      filter without variation)};
    * ``t_start_s``, ``t_end_s``, ``t_span_s`` (capture clock, s), ``fixes_fused``
      (positions the filter took: initialisation, gate passes, manoeuvres,
      resets);
    * ``estimate`` at ``t_end_s``: ``pos_valid``, ``heading_valid``,
      ``pos_ever_valid``, ``heading_ever_valid`` (after any message),
      ``fix`` (last received), ``lat_deg``/``lon_deg`` (WGS-84 deg) and
      ``x_m``/``y_m`` (local NED, m) and ``pos_sigma_m`` — None unless the
      position was ever valid —, ``gps_age_s``, ``heading_deg`` (true, [0, 360),
      the compass's reference when ``magnetic_uncorrected``),
      ``heading_sigma_deg`` (1σ), ``compass_bias_deg`` (compass − heading),
      ``gyro_bias_dps`` (ROT − yaw rate, deg/s), each with its 1σ
      (``compass_bias_sigma_deg``, ``gyro_bias_sigma_dps``: still the prior when
      nothing made the bias observable), ``yaw_rate_dps`` (deg/s,
      clockwise +), ``speed_mps`` (over ground), ``current_n_mps`` /
      ``current_e_mps``, ``compass_faults`` (sources flagged frozen/jumping);
    * ``gate_rejections`` (``total`` and by measurement kind), ``resets`` (by
      kind), ``counters`` (all of :attr:`EkfStatus.counters`);
    * ``errors`` (EKF exceptions; 0 for a sound run), ``error_samples``.
    """
    cap = read_capture(path, variation_deg, line_rate_hz)
    msgs = cap.messages
    first = next((m for m in msgs if isinstance(m, GpsFix) and m.fix > FixQuality.NONE
                  and m.lat_deg is not None and m.lon_deg is not None), None)
    lat0, lon0 = (first.lat_deg, first.lon_deg) if first is not None else (0.0, 0.0)
    assert lat0 is not None and lon0 is not None
    nav = EkfNavigator(EkfSettings(), LocalFrame(lat0, lon0), None)
    errors: list[str] = []
    pos_ever = hdg_ever = False
    for m in msgs:
        handler = nav.handler(m)
        if handler is None:
            continue
        try:
            handler(m)
            st = nav.state(m.t)
            pos_ever |= st.pos_valid
            hdg_ever |= st.heading_valid
        except Exception as exc:  # the report's point: count it and carry on
            errors.append(f"{type(m).__name__} at t={m.t:.3f} s: "
                          f"{type(exc).__name__}: {exc}")
    t_start = msgs[0].t if msgs else 0.0
    t_end = msgs[-1].t if msgs else 0.0
    estimate: dict[str, Any] = {}
    counters: dict[str, int] = {}
    fused = 0
    try:
        st = nav.state(t_end)
        status = nav.status(t_end)
        counters = dict(status.counters)
        c = counters.get
        fused = (c("pos_ok", 0) + c("pos_manoeuvre", 0) + c("resets_pos", 0)
                 + (1 if math.isfinite(status.gps_age_s) else 0))
        s, sg = status.state, status.sigma
        pos = pos_ever
        estimate = {
            "pos_valid": status.pos_valid, "heading_valid": status.heading_valid,
            "pos_ever_valid": pos_ever, "heading_ever_valid": hdg_ever,
            "fix": st.fix.label,
            "lat_deg": _r(st.lat_deg, 8) if pos else None,
            "lon_deg": _r(st.lon_deg, 8) if pos else None,
            "x_m": _r(st.x_m, 3) if pos else None,
            "y_m": _r(st.y_m, 3) if pos else None,
            "pos_sigma_m": _r(status.pos_sigma_m, 3) if pos else None,
            "gps_age_s": _r(status.gps_age_s, 3),
            "heading_deg": _r(math.degrees(st.psi_rad) % 360.0, 3),
            "heading_sigma_deg": _r(status.heading_sigma_deg, 3),
            "compass_bias_deg": _r(math.degrees(s["compass_bias_rad"]), 3),
            "compass_bias_sigma_deg": _r(math.degrees(sg["compass_bias_rad"]), 3),
            "gyro_bias_dps": _r(math.degrees(s["gyro_bias_rps"]), 5),
            "gyro_bias_sigma_dps": _r(math.degrees(sg["gyro_bias_rps"]), 5),
            "yaw_rate_dps": _r(math.degrees(st.r_rps), 5),
            "speed_mps": _r(math.hypot(st.vn_mps, st.ve_mps), 3),
            "current_n_mps": _r(s["current_n_mps"], 3),
            "current_e_mps": _r(s["current_e_mps"], 3),
            "compass_faults": list(status.compass_faults),
        }
    except Exception as exc:  # as above: reported, not raised
        errors.append(f"final state at t={t_end:.3f} s: {type(exc).__name__}: {exc}")
    rejections = {k: counters.get(f"{k}_rejected", 0) for k in KIND_NAMES}
    resets = {k: counters.get(f"resets_{k}", 0) for k in KIND_NAMES}
    uncorrected = cap.headings["uncorrected"] > 0
    return {
        "file": str(path),
        "timing": "utc" if cap.timed else "line_rate",
        "line_rate_hz": None if cap.timed else line_rate_hz,
        "sentences": cap.sentences,
        "refused": {"total": sum(cap.refused.values()),
                    "by_reason": dict(sorted(cap.refused.items())),
                    "by_kind": dict(sorted(cap.refused_kind.items()))},
        "messages": dict(sorted(Counter(type(m).__name__ for m in msgs).items())),
        "fix_types": dict(sorted(Counter(m.fix.label for m in msgs
                                         if isinstance(m, GpsFix)).items())),
        "origin": {"lat_deg": lat0, "lon_deg": lon0,
                   "from": "first_fix" if first is not None else "none"},
        "variation": {"deg": cap.variation_deg if cap.variation_deg is not None else 0.0,
                      "source": cap.variation_source,
                      "headings": dict(sorted(cap.headings.items())),
                      "magnetic_uncorrected": uncorrected},
        "t_start_s": round(t_start, 3), "t_end_s": round(t_end, 3),
        "t_span_s": round(t_end - t_start, 3),
        "fixes_fused": fused,
        "estimate": estimate,
        "gate_rejections": {"total": sum(rejections.values()), **rejections},
        "resets": {"total": sum(resets.values()), **resets},
        "counters": dict(sorted(counters.items())),
        "errors": len(errors),
        "error_samples": errors[:ERROR_SAMPLES],
    }


# ------------------------------------------------------------------- CLI
def _counts(d: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in d.items()) or "-"


def _num(v: Any, fmt: str, unit: str = "") -> str:
    return "-" if v is None else f"{v:{fmt}}{unit}"


def report_table(rep: dict[str, Any]) -> str:
    """A short human-readable table of one :func:`capture_report`."""
    e = rep["estimate"]
    ref = rep["refused"]
    var = rep["variation"]
    timing = ("by its UTC" if rep["timing"] == "utc"
              else f"at {rep['line_rate_hz']:g} sentences/s (no UTC in it)")
    origin = rep["origin"]
    org = (f"{origin['lat_deg']:.7f}, {origin['lon_deg']:.7f} (first fix)"
           if origin["from"] == "first_fix" else "0, 0 (no fix in the capture)")
    if var["magnetic_uncorrected"]:
        ref_txt = "magnetic, NOT corrected (no variation)"
    elif var["source"] == "none":
        ref_txt = "true"
    else:
        ref_txt = f"true (variation {var['deg']:+g}° from the {var['source']})"
    rows = [
        (rep["file"], f"{rep['sentences']} sentences, timed {timing}, "
                      f"{rep['t_span_s']:.3f} s"),
        ("refused", f"{ref['total']}  by reason: {_counts(ref['by_reason'])}; "
                    f"by type: {_counts(ref['by_kind'])}"),
        ("messages", _counts(rep["messages"])),
        ("fixes", f"types {_counts(rep['fix_types'])}; fused {rep['fixes_fused']}"),
        ("origin", org),
    ]
    if e:
        pos = "valid" if e["pos_valid"] else "not valid"
        if e["lat_deg"] is not None:
            pos += (f"  {e['lat_deg']:.7f}, {e['lon_deg']:.7f}  x {e['x_m']:.2f} m "
                    f"y {e['y_m']:.2f} m  σ {e['pos_sigma_m']:.2f} m  ({e['fix']})")
        rows += [
            ("position", pos),
            ("heading", f"{_num(e['heading_deg'], '.2f', '°')} ± "
                        f"{_num(e['heading_sigma_deg'], '.2f', '°')} "
                        f"{'valid' if e['heading_valid'] else 'not valid'}, {ref_txt}"),
            ("biases", f"compass {_num(e['compass_bias_deg'], '+.3f', '°')} ± "
                       f"{_num(e['compass_bias_sigma_deg'], '.3f', '°')}, gyro "
                       f"{_num(e['gyro_bias_dps'], '+.5f', '°/s')} ± "
                       f"{_num(e['gyro_bias_sigma_dps'], '.5f', '°/s')}"),
            ("motion", f"yaw rate {_num(e['yaw_rate_dps'], '+.5f', '°/s')}, speed "
                       f"{_num(e['speed_mps'], '.3f', ' m/s')}"),
        ]
    rows += [
        ("gates", f"rejected {rep['gate_rejections']['total']}, resets "
                  f"{rep['resets']['total']}, compass faults "
                  f"{', '.join(e.get('compass_faults', [])) or '-'}"),
        ("EKF errors", str(rep["errors"])),
    ]
    width = max(len(k) for k, _ in rows[1:])
    head, *rest = rows
    return "\n".join([f"{head[0]}: {head[1]}"]
                     + [f"  {k:<{width}}  {v}" for k, v in rest]
                     + [f"  {'':<{width}}  {s}" for s in rep["error_samples"]])


def main_navreport(paths: list[str], variation_deg: float | None = None,
                   line_rate_hz: float = 5.0, out: IO[str] | None = None,
                   err: IO[str] | None = None) -> int:
    """``zarco navreport``: a table per capture on ``err``, then one JSON line on
    ``out`` (a dict keyed by the paths as given; ``{"error": ...}`` for a file
    that could not be read).  0: every capture ran with no EKF error; 1: some
    EKF error; 2: a file could not be read (missing)."""
    out = out or sys.stdout
    err = err or sys.stderr
    reports: dict[str, Any] = {}
    rc = 0
    for p in paths:
        try:
            rep = capture_report(Path(p), variation_deg, line_rate_hz)
        except OSError as exc:
            err.write(f"zarco navreport: {p}: {exc.strerror or exc}\n")
            reports[p] = {"error": exc.strerror or str(exc)}
            rc = 2
            continue
        reports[p] = rep
        err.write(report_table(rep) + "\n\n")
        if rep["errors"] and rc == 0:
            rc = 1
    out.write(json.dumps(reports, allow_nan=False, separators=(",", ":")) + "\n")
    return rc
