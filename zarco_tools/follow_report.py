"""Figures of a simulated follow-the-AUV mission, against the truth.

* ``fix_interval_s``: median time between accepted passive fixes (emission times);
* ``fix_error_rms_m``: accepted fixes vs the AUV's true position at emission;
* ``track_error_rms_m``: the tracker's Kalman filter vs truth;
* ``course_error_rms_deg``: the RLS course vs the true course, on straight legs
  from 30 s after each manoeuvre;
* ``acquired_s``: acquisition, the first time the follow guidance steers by
  the AUV's track (the supervisor's "AUV acquired; following"); None if never;
* ``distance_median_m``, ``distance_p95_m``, ``distance_max_m``: the ASV–AUV
  horizontal distance over the whole followed time, from acquisition to the
  end of the run (the approach, every turn, every loss included);
* ``time_above_4m_s``: where the whole-time p95 goes — the seconds further
  than 4 m from the AUV by phase (``hover``, ``set_off``, ``turn``,
  ``uturn``, ``arc``, ``straight``), their ``total`` and the ``budget`` a p95
  within 4 m allows (5 % of the followed time): :mod:`zarco_tools.follow_distance`;
* ``settled_distance_median_m``, ``settled_distance_p95_m``: the same on
  straight legs only, leaving out the minute after each manoeuvre (and after
  the AUV starts moving);
* ``turns``: per AUV manoeuvre (leg switches less than 30 s after the previous
  one, such as a lawnmower's two 90° turns at the end of a leg, count as one;
  a continuous turn is one manoeuvre however far it turns) its start ``t_s``
  and end ``end_s``, net course change ``angle_deg`` (positive to starboard),
  ``kind`` (``turn`` up to 90°, ``uturn`` beyond, ``arc`` a continuous turn:
  an arc, a circle, a spiral), ``detect_s`` (from its start until the course
  error stays under 10°), ``distance_max_m`` (from its start to the next
  manoeuvre) and ``recovery_s`` (from its start until the ASV is within 3 m
  of the AUV and stays so for 10 s; None if it never is):
  :mod:`zarco_tools.follow_distance`;
* ``lost_max_s``: the longest time, once the AUV moves, that the ASV was not
  following it (the follow guidance holding: track lost, or the AUV taken for
  still) while the AUV was heard (detected interrogations at most 2.5 s apart);
  ``hold_max_s`` the same whether heard or not, ``fix_gap_max_s`` the longest
  time without an accepted update;
* ``sound_speed_est_mps``: the tracker's final estimate of the sound speed (the
  configured value when the tracker keeps it fixed), ``sound_speed_true_mps``
  the simulated truth, ``sound_speed_configured_mps`` what the tracker was
  configured with, ``sound_speed_error_max_pct`` the largest
  |estimate − truth| / truth (%) from 300 s after acquisition to the end.

Every figure that cannot be computed (no turn recovered, no straight leg) is
None, never NaN: the report is written as JSON.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from zarco_core.auv_messages import AuvFix, AuvTrack, TrackFlags
from zarco_tools.follow_distance import (
    PHASES,
    Manoeuvre,
    manoeuvre_rows,
    merge_manoeuvres,
    settled_figures,
    settled_windows,
    time_above_by_phase,
    whole_figures,
)
from zarco_tools.sim_report import TrackLog

COURSE_SETTLE_S = 30.0
DETECT_DEG = 10.0
#: the AUV counts as heard while its detected interrogations are no further
#: apart than this (s; it pings every 1–2 s, so a longer silence is missed pings)
HEARD_GAP_S = 2.5
#: the sound-speed estimate is judged from this long after acquisition (s)
SOUND_SPEED_SETTLE_S = 300.0
#: the AUV counts as moving between true-track samples 0.1 s apart when it
#: moved more than this (m): 0.2 m/s
MOVING_STEP_M = 0.02


def finite_or_none(v: Any) -> Any:
    """``v`` with every non-finite float (NaN, ±inf) replaced by None, through
    dicts, lists and tuples: what JSON can hold."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: finite_or_none(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [finite_or_none(x) for x in v]
    return v


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _inside(t: float, wins: list[tuple[float, float]]) -> bool:
    return any(a <= t < b for a, b in wins)


def _longest(t: np.ndarray, bad: np.ndarray) -> float:
    """Longest contiguous time (s) over samples ``t`` where ``bad`` holds."""
    best = 0.0
    start = None
    for tt, b in zip(t, bad, strict=True):
        if b and start is None:
            start = tt
        elif not b and start is not None:
            best = max(best, float(tt - start))
            start = None
    if start is not None and t.size:
        best = max(best, float(t[-1] - start))
    return best


def _longest_counted(t: np.ndarray, bad: np.ndarray, count: np.ndarray) -> float:
    """Longest contiguous stretch where ``bad`` holds, measured only over the
    samples where ``count`` holds (s)."""
    best = run = 0.0
    for i in range(1, t.size):
        if bad[i] and bad[i - 1]:
            if count[i]:
                run += float(t[i] - t[i - 1])
            best = max(best, run)
        elif not bad[i]:
            run = 0.0
    return best


def acquisition_time(modes: list[tuple[float, str]]) -> float | None:
    """The first time (s) the follow guidance steered by the AUV's track
    (phase ``follow`` of the guidance modes ``(t, mode)``), or None."""
    return next((t for t, m in modes if m == "follow:follow"), None)


def sound_speed_figures(tracks: list[AuvTrack], configured: float, true: float,
                        acquired_s: float | None) -> dict[str, float]:
    """The tracker's final sound-speed estimate (the configured value when its
    tracks carry none), the truth, and the largest relative error (%) from
    ``SOUND_SPEED_SETTLE_S`` after acquisition on (NaN when the run ended
    before, or never acquired)."""

    def est(tr: AuvTrack) -> float:
        v = getattr(tr, "sound_speed_mps", math.nan)
        return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else configured

    final = est(tracks[-1]) if tracks else configured
    err = math.nan
    if acquired_s is not None:
        late = [abs(est(tr) - true) / true * 100.0 for tr in tracks
                if tr.t >= acquired_s + SOUND_SPEED_SETTLE_S]
        err = max(late) if late else math.nan
    return {"sound_speed_est_mps": final, "sound_speed_true_mps": true,
            "sound_speed_configured_mps": configured, "sound_speed_error_max_pct": err}


def follow_figures(log: TrackLog, counters: dict[str, Any]) -> dict[str, Any]:
    """The figures of the module's docstring, from the true-track ``log`` and
    the simulation's ``counters`` (the acoustic world, the tracker's messages,
    the guidance modes, the runtime)."""
    acoustics = counters["acoustics"]
    auv = acoustics.auv
    msgs = counters.get("auv_msgs", [])
    auv_log = counters.get("auv_log", [])
    t_end = log.t[-1] if log.t else 0.0
    man = merge_manoeuvres([Manoeuvre(m.start_s, m.end_s, m.angle_rad, m.arc)
                            for m in auv.manoeuvres()], t_end)
    move_start = float(auv.params.start_delay_s)
    acquired = acquisition_time(counters.get("guidance_modes", []))

    fixes = [m for m in msgs if isinstance(m, AuvFix) and m.accepted and not m.range_only]
    updates = sorted(acoustics.sim_time(m.emission_utc_s) for m in msgs
                     if isinstance(m, AuvFix) and m.accepted)
    tracks = [m for m in msgs if isinstance(m, AuvTrack)]
    em = np.array([acoustics.sim_time(f.emission_utc_s) for f in fixes])
    fix_interval = float(np.median(np.diff(em))) if em.size > 2 else math.nan
    ferr = []
    for f, te in zip(fixes, em, strict=True):
        a = acoustics.auv_truth(float(te))
        ferr.append(math.hypot(f.x_m - a.x_m, f.y_m - a.y_m))
    terr, course_t, course_err = [], [], []
    for tr in tracks:
        if tr.lost or not tr.flags & TrackFlags.INITIALISED:
            continue
        a = acoustics.auv_truth(acoustics.sim_time(tr.t0_utc_s))
        terr.append(math.hypot(tr.kf_x_m - a.x_m, tr.kf_y_m - a.y_m))
        at = acoustics.auv_truth(tr.t)
        moving = at.speed_mps >= 0.5 * auv.params.speed_mps
        if moving and tr.flags & TrackFlags.LINE_VALID and math.isfinite(tr.psi_auv_rad):
            course_t.append(tr.t)
            course_err.append(abs(math.degrees(math.remainder(tr.psi_auv_rad - at.psi_rad,
                                                             math.tau))))
    cwins = settled_windows(move_start, man, t_end, COURSE_SETTLE_S)
    c_sel = [e for t, e in zip(course_t, course_err, strict=True) if _inside(t, cwins)]

    t = np.asarray(log.t)
    dist = np.array([math.hypot(x - a[1], y - a[2])
                     for x, y, a in zip(log.x, log.y, auv_log, strict=False)])
    t = t[: dist.size]
    moving = np.array([math.hypot(a[1] - b[1], a[2] - b[2]) > MOVING_STEP_M
                       for a, b in zip(auv_log[1:], auv_log[:-1], strict=True)] + [False])
    moving = moving[: dist.size]

    turn_rows: list[dict[str, Any]] = []
    for m, row in zip(man, manoeuvre_rows(t, dist, man, t_end), strict=True):
        nxt = m.start_s + float(row["window_s"])
        detect = math.nan
        after = [(tt, e) for tt, e in zip(course_t, course_err, strict=True)
                 if m.start_s <= tt < nxt]
        for j, (tt, _e) in enumerate(after):
            if all(e2 < DETECT_DEG for _t2, e2 in after[j:]):
                detect = tt - m.start_s
                break
        turn_rows.append({**row, "detect_s": _num(detect)})

    # lost: the longest time, once the AUV moves, without an accepted update or
    # with the track declared lost
    upd = np.array([u for u in updates if u <= t_end])
    if upd.size:
        pts = np.concatenate([[max(move_start, float(upd[0]))],
                              upd[upd > move_start], [t_end]])
        gap = float(np.max(np.diff(pts))) if pts.size > 1 else 0.0
    else:
        gap = max(0.0, t_end - move_start)
    # not following the AUV (holding: the track lost, or the AUV taken for still)
    # once it moves, counting only the time the listener hears its interrogations
    legs = np.asarray(log.leg[: t.size])
    after_move = t >= move_start
    hold = _longest(t[after_move], legs[after_move] < 0) if after_move.any() else 0.0
    heard_i = np.array(sorted(d.t_s for d in acoustics.detections
                              if d.kind == "I" and d.label != "false"))
    if heard_i.size > 1 and t.size:
        k = np.clip(np.searchsorted(heard_i, t), 1, heard_i.size - 1)
        heard = (heard_i[k] - heard_i[k - 1]) <= HEARD_GAP_S
    else:
        heard = np.zeros(t.size, dtype=bool)
    lost = _longest_counted(t[after_move], (legs < 0)[after_move], heard[after_move])

    def rms(v: list[float]) -> float:
        return float(np.sqrt(np.mean(np.square(v)))) if v else math.nan

    runtime = counters.get("runtime")
    configured = (float(runtime.cfg.tracker.network.sound_speed_mps) if runtime is not None
                  else float(acoustics.c))
    figures: dict[str, Any] = finite_or_none({
        "fix_interval_s": fix_interval,
        "fixes": len(fixes),
        "fix_error_rms_m": rms(ferr),
        "track_error_rms_m": rms(terr),
        "course_error_rms_deg": rms(c_sel),
        "turns": turn_rows,
        "acquired_s": acquired if acquired is not None else math.nan,
        **whole_figures(t, dist, acquired),
        "time_above_4m_s": time_above_by_phase(t, dist, acquired, move_start, man),
        **settled_figures(t, dist, moving, acquired,
                          settled_windows(move_start, man, t_end)),
        **sound_speed_figures(tracks, configured, float(acoustics.c), acquired),
        "track_lost_events": sum(1 for tr in tracks if tr.lost),
        "fix_gap_max_s": round(gap, 2),
        "hold_max_s": round(hold, 2),
        "lost_max_s": round(lost, 2),
    })
    return figures


def _fmt(v: Any, unit: str = "m", digits: int = 3) -> str:
    return f"{v:.{digits}f} {unit}" if isinstance(v, (int, float)) else "—"


def above_line(above: dict[str, float]) -> str:
    """The time further than 4 m from the AUV, by phase, against the budget a
    p95 within 4 m allows (one line; the breakdown of ``time_above_4m_s``)."""
    if not above:
        return "further than 4 m: — (never acquired)"
    parts = ", ".join(f"{p.replace('_', '-')} {above[p]:.1f}" for p in PHASES
                      if above.get(p))
    return (f"further than 4 m from the AUV {above['total']:.1f} s (a p95 within 4 m "
            f"allows {above['budget']:.1f} s)" + (f": {parts} s" if parts else ""))


def follow_summary(report: dict[str, Any]) -> str:
    """One screen of a follow-the-AUV run, each figure labelled with what it
    covers."""
    acq = report.get("acquired_s")
    lines = [
        f"scenario {report['scenario']}  seed {report['seed']}  ({report['stop']})",
        f"simulated {report['sim_seconds']:.1f} s in {report['wall_seconds']:.2f} s wall "
        f"= {report['speedup']:.0f}× real time",
        f"passive fixes: {report['fixes']}, median interval "
        f"{_fmt(report['fix_interval_s'], 's')}, "
        f"error RMS {_fmt(report['fix_error_rms_m'])}; track error RMS "
        f"{_fmt(report['track_error_rms_m'])}",
        f"AUV course error RMS (straight legs) {_fmt(report['course_error_rms_deg'], '°')}",
        f"ASV–AUV distance, whole run from acquisition "
        f"({_fmt(acq, 's', 1) if acq is not None else 'never acquired'}) to the end: "
        f"median {_fmt(report['distance_median_m'])}  p95 {_fmt(report['distance_p95_m'])}  "
        f"max {_fmt(report['distance_max_m'])}",
        f"ASV–AUV distance, settled (straight legs, without the minute after each "
        f"manoeuvre): median {_fmt(report.get('settled_distance_median_m'))}  "
        f"p95 {_fmt(report.get('settled_distance_p95_m'))}",
        above_line(report.get("time_above_4m_s") or {}),
        f"sound speed: tracker's estimate {_fmt(report.get('sound_speed_est_mps'), 'm/s', 1)}"
        f", true {_fmt(report.get('sound_speed_true_mps'), 'm/s', 1)} (configured "
        f"{_fmt(report.get('sound_speed_configured_mps'), 'm/s', 1)}); largest error from "
        f"{SOUND_SPEED_SETTLE_S:.0f} s after acquisition "
        f"{_fmt(report.get('sound_speed_error_max_pct'), '%', 2)}",
        f"track lost {report['track_lost_events']} times; longest without a usable track "
        f"{_fmt(report.get('lost_max_s'), 's')}",
        "",
        " turn at  kind     angle   detect     recovery   max distance",
    ]

    def f(v: Any, fmt: str) -> str:
        return format(v, fmt) if isinstance(v, (int, float)) else "   —  "

    for tr in report["turns"]:
        lines.append(f" {tr['t_s']:7.1f}  {tr.get('kind', ''):<6} "
                     f"{f(tr.get('angle_deg'), '6.0f')}°  "
                     f"{f(tr['detect_s'], '6.1f')} s  {f(tr['recovery_s'], '6.1f')} s  "
                     f"{f(tr['distance_max_m'], '7.2f')} m")
    return "\n".join(lines)
