"""What the navigation EKF estimates from a recorded NMEA capture.

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
    GpsVelocity,
    Heading,
    NavState,
)
from zarco_runtime.navigation.ekf import KIND_NAMES, EkfNavigator, EkfStatus
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


#: 1σ of an angle that is uniformly unknown on the circle (deg): 180/√3; a heading
#: σ at or beyond it says nothing, and is reported as not estimated
ANGLE_UNKNOWN_DEG = 180.0 / math.sqrt(3.0)
#: a state whose σ is still this fraction of its prior (or more) was not estimated:
#: nothing in the capture informed it
PRIOR_SHARE = 0.9


def _estimate(cfg: EkfSettings, st: NavState, status: EkfStatus, counters: dict[str, int],
              pos_ever: bool, hdg_ever: bool, cap: Capture) -> dict[str, Any]:
    """The estimate at the end of a capture, each value with its 1σ, or None with the
    reason it could not be estimated (``not_estimated``: quantity → reason)."""
    c = counters.get
    s, sg = status.state, status.sigma
    why: dict[str, str] = {}
    n_fix = sum(1 for m in cap.messages if isinstance(m, GpsFix) and m.fix > FixQuality.NONE
                and m.lat_deg is not None)
    n_vel = c("vel_ok", 0) + c("sog_ok", 0) + c("vel_manoeuvre", 0)
    compass = c("compass_ok", 0) > 0
    true_hdg = c("true_heading_ok", 0) > 0
    gyro = c("rot_ok", 0) > 0
    course = c("heading_from_course", 0) > 0
    # ---- position
    if not pos_ever:
        if n_fix == 0:
            why["position"] = "no GPS fix in the capture"
        elif c("pos_below_min_fix", 0):
            why["position"] = (f"no fix as good as ekf.min_fix = {cfg.min_fix!r} "
                               f"({c('pos_below_min_fix', 0)} worse ones)")
        else:
            why["position"] = (f"never valid: its 1σ stayed above ekf.pos_sigma_max_m = "
                               f"{cfg.pos_sigma_max_m:g} m")
    elif not status.pos_valid:
        why["position_at_end"] = (
            "not valid at the end: " + (
                f"the last fused fix is {status.gps_age_s:.1f} s old (dead reckoning ends "
                f"after ekf.dr_max_s = {cfg.dr_max_s:g} s)" if status.gps_age_s > cfg.dr_max_s
                else f"its 1σ {status.pos_sigma_m:.1f} m is above ekf.pos_sigma_max_m = "
                     f"{cfg.pos_sigma_max_m:g} m") + "; the position shown is the last "
            "estimate")
    pos = pos_ever
    # ---- heading
    hdg_sigma = status.heading_sigma_deg
    heading = True
    if not (compass or true_hdg or course):
        heading = False
        why["heading"] = ("no compass or true heading (HDT/THS) in the capture, and the GPS "
                          "course could not stand in: the boat never moved at "
                          f"≥ {cfg.course_init_speed_mps:g} m/s (ekf.course_init_speed_mps)")
    elif not hdg_sigma < ANGLE_UNKNOWN_DEG:
        heading = False
        why["heading"] = (f"lost: its 1σ grew to {hdg_sigma:.0f}° (≥ {ANGLE_UNKNOWN_DEG:.0f}°, "
                          "a heading anywhere on the circle) since the last heading")
    elif course and not (compass or true_hdg):
        why["heading_source"] = ("from the GPS course (no heading sensor): the direction of "
                                 "travel, not of the bow; flagged not valid")
    # ---- compass bias
    bc_prior = math.radians(cfg.compass_bias_sigma_deg)
    compass_bias = compass and sg["compass_bias_rad"] < PRIOR_SHARE * bc_prior
    if not compass:
        why["compass_bias"] = ("no compass heading in the capture" + (
            " (its headings are true headings, which have no bias)" if true_hdg else ""))
    elif not compass_bias:
        why["compass_bias"] = (
            "not observable: a compass bias shows against a true heading (HDT/THS from "
            "ekf.true_heading_sources) or as the angle between heading and GPS course while "
            "the boat moves and turns; " + ("the boat did not move or turn enough" if n_vel
                                            else "the capture has no GPS velocity") +
            (" and no true heading" if not true_hdg else ""))
    # ---- gyro bias and yaw rate
    bg_prior = math.radians(cfg.gyro_bias_sigma_dps)
    gyro_bias = gyro and sg["gyro_bias_rps"] < PRIOR_SHARE * bg_prior
    if not gyro:
        why["gyro_bias"] = "no rate of turn (ROT) in the capture"
    elif not gyro_bias:
        why["gyro_bias"] = ("not observable: the gyro bias is learned against the change of "
                            "a heading over time, and the capture's headings are too few or "
                            "too short")
    yaw_rate = gyro or ((compass or true_hdg) and heading)
    if not yaw_rate:
        why["yaw_rate"] = "no rate of turn (ROT) and no heading sensor in the capture"
    # ---- speed over ground
    vcov = st.cov
    speed = math.hypot(st.vn_mps, st.ve_mps)
    speed_sigma = math.nan
    if len(vcov) == 25:
        pvv = max(vcov[12], vcov[18])  # the worse of vn, ve
        speed_sigma = math.sqrt(max(pvv, 0.0))
    speed_ok = (n_vel > 0 or c("pos_ok", 0) >= 2) and speed_sigma < PRIOR_SHARE * 2.0
    n_vel_msgs = sum(1 for m in cap.messages if isinstance(m, GpsVelocity))
    if not speed_ok:
        if n_vel_msgs and not (compass or true_hdg or course):
            why["speed"] = ("the GPS velocity is fused as a speed through the water along "
                            "a heading, and there is none (see heading); too few fused fixes "
                            "to tell a speed from positions")
        elif n_vel == 0 and c("pos_ok", 0) < 2:
            why["speed"] = "no GPS velocity (RMC/VTG) and fewer than two fused fixes"
        else:
            why["speed"] = f"its 1σ is still {speed_sigma:.1f} m/s"
    # ---- current
    cur_prior = cfg.current_sigma_mps
    cur_sigma = max(s_ for s_ in (sg["current_n_mps"], sg["current_e_mps"]))
    current = (cfg.estimate_current and cur_sigma < PRIOR_SHARE * cur_prior and heading
               and (compass or true_hdg))
    if not cfg.estimate_current:
        why["current"] = "not estimated (ekf.estimate_current = false)"
    elif not current:
        why["current"] = ("not observable: the current is the GPS velocity less the velocity "
                          "through the water, which needs a heading sensor and a boat that "
                          "moves and turns; " + ("there is no heading sensor" if not
                                                  (compass or true_hdg) else
                                                  "the capture does not show enough of that"))


    def val(ok: bool, x: float, nd: int) -> float | None:
        return _r(x, nd) if ok else None

    d = math.degrees
    return {
        "pos_valid": status.pos_valid, "heading_valid": status.heading_valid,
        "pos_ever_valid": pos_ever, "heading_ever_valid": hdg_ever,
        "fix": st.fix.label,
        "lat_deg": val(pos, st.lat_deg, 8),
        "lon_deg": val(pos, st.lon_deg, 8),
        "x_m": val(pos, st.x_m, 3),
        "y_m": val(pos, st.y_m, 3),
        "pos_sigma_m": val(pos, status.pos_sigma_m, 3),
        "gps_age_s": _r(status.gps_age_s, 3),
        "heading_deg": val(heading, d(st.psi_rad) % 360.0, 3),
        "heading_sigma_deg": val(heading, hdg_sigma, 3),
        "compass_bias_deg": val(compass_bias, d(s["compass_bias_rad"]), 3),
        "compass_bias_sigma_deg": val(compass_bias, d(sg["compass_bias_rad"]), 3),
        "gyro_bias_dps": val(gyro_bias, d(s["gyro_bias_rps"]), 5),
        "gyro_bias_sigma_dps": val(gyro_bias, d(sg["gyro_bias_rps"]), 5),
        "yaw_rate_dps": val(yaw_rate, d(st.r_rps), 5),
        "yaw_rate_sigma_dps": val(yaw_rate, d(sg["r_rps"]), 5),
        "speed_mps": val(speed_ok, speed, 3),
        "speed_sigma_mps": val(speed_ok, speed_sigma, 3),
        "current_n_mps": val(current, s["current_n_mps"], 3),
        "current_e_mps": val(current, s["current_e_mps"], 3),
        "current_sigma_mps": val(current, cur_sigma, 3),
        "compass_faults": list(status.compass_faults),
        "not_estimated": why,
    }


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
        estimate = _estimate(nav.cfg, st, status, counters, pos_ever, hdg_ever, cap)
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
    elif e and "heading_source" in e.get("not_estimated", {}):
        ref_txt = "course over ground"
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
        why = e.get("not_estimated", {})

        def pm(key: str, fmt: str, unit: str, sig: str, sfmt: str, what: str) -> str:
            if e[key] is None:
                return f"not estimated: {why.get(what, 'no information')}"
            return f"{e[key]:{fmt}}{unit} ± {e[sig]:{sfmt}}{unit}"

        pos = "valid" if e["pos_valid"] else "not valid"
        if e["lat_deg"] is not None:
            pos += (f"  {e['lat_deg']:.7f}, {e['lon_deg']:.7f}  x {e['x_m']:.2f} m "
                    f"y {e['y_m']:.2f} m  σ {e['pos_sigma_m']:.2f} m  ({e['fix']})")
        else:
            pos += f": {why.get('position', 'no information')}"
        if "position_at_end" in why:
            pos += f"; {why['position_at_end']}"
        hdg = pm("heading_deg", ".2f", "°", "heading_sigma_deg", ".2f", "heading")
        if e["heading_deg"] is not None:
            hdg += f" {'valid' if e['heading_valid'] else 'not valid'}, {ref_txt}"
            if "heading_source" in why:
                hdg += f"; {why['heading_source']}"
        cur = (f"north {e['current_n_mps']:+.3f} m/s, east {e['current_e_mps']:+.3f} m/s "
               f"± {e['current_sigma_mps']:.3f} m/s" if e["current_n_mps"] is not None
               else f"not estimated: {why.get('current', 'no information')}")
        rows += [
            ("position", pos),
            ("heading", hdg),
            ("compass bias", pm("compass_bias_deg", "+.3f", "°", "compass_bias_sigma_deg",
                                ".3f", "compass_bias")),
            ("gyro bias", pm("gyro_bias_dps", "+.5f", "°/s", "gyro_bias_sigma_dps", ".5f",
                             "gyro_bias")),
            ("yaw rate", pm("yaw_rate_dps", "+.4f", "°/s", "yaw_rate_sigma_dps", ".4f",
                            "yaw_rate")),
            ("speed", pm("speed_mps", ".3f", " m/s", "speed_sigma_mps", ".3f", "speed")),
            ("current", cur),
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
