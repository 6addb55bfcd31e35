"""Figures of a simulated follow-the-AUV mission (issue #3), against the truth.

* ``fix_interval_s``: median time between accepted passive fixes (emission times);
* ``fix_error_rms_m``: accepted fixes vs the AUV's true position at emission;
* ``track_error_rms_m``: the tracker's Kalman filter vs truth;
* ``course_error_rms_deg``: the RLS course vs the true course, on straight legs
  from 30 s after each turn;
* ``turns``: per AUV turn (two turns less than a minute apart, such as a
  lawnmower's U-turn, count as one), ``detect_s`` (from the start of the turn until the
  course error stays under 10°) and ``recovery_s`` (until the ASV–AUV
  horizontal distance stays ≤ 3 m for 10 s);
* ``distance_median_m``, ``distance_p95_m`` on straight legs from 60 s after
  each turn (and after the AUV starts moving), ``distance_max_m`` over the
  whole run.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from zarco_core.auv_messages import AuvFix, AuvTrack, TrackFlags
from zarco_tools.sim_report import TrackLog

COURSE_SETTLE_S = 30.0
DISTANCE_SETTLE_S = 60.0
DETECT_DEG = 10.0
RECOVER_M = 3.0
RECOVER_HOLD_S = 10.0
MERGE_S = 60.0


def _windows(starts: list[float], stops: list[float], end: float,
             settle: float) -> list[tuple[float, float]]:
    """Straight-leg windows: from ``settle`` after each start (the end of a
    manoeuvre) to the next stop (the start of the next one)."""
    out = []
    for i, s in enumerate(starts):
        e = stops[i] if i < len(stops) else end
        if s + settle < e:
            out.append((s + settle, e))
    return out


def _inside(t: float, wins: list[tuple[float, float]]) -> bool:
    return any(a <= t < b for a, b in wins)


def follow_figures(log: TrackLog, counters: dict[str, Any]) -> dict[str, Any]:
    acoustics = counters["acoustics"]
    auv = acoustics.auv
    msgs = counters.get("auv_msgs", [])
    auv_log = counters.get("auv_log", [])
    t_end = log.t[-1] if log.t else 0.0
    # turns closer together than MERGE_S (a lawnmower's two 90° turns at the end
    # of a leg) count as one manoeuvre
    turns: list[float] = []
    turn_ends: list[float] = []
    for tt_ in auv.turn_times():
        if tt_ >= t_end:
            continue
        if turns and tt_ - turn_ends[-1] <= MERGE_S:
            turn_ends[-1] = tt_
        else:
            turns.append(tt_)
            turn_ends.append(tt_)
    move_start = float(auv.params.start_delay_s)
    # straight legs start after the last turn of each manoeuvre
    starts = [move_start, *turn_ends]

    fixes = [m for m in msgs if isinstance(m, AuvFix) and m.accepted and not m.range_only]
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
    cwins = _windows(starts, turns, t_end, COURSE_SETTLE_S)
    c_sel = [e for t, e in zip(course_t, course_err, strict=True) if _inside(t, cwins)]

    t = np.asarray(log.t)
    dist = np.array([math.hypot(x - a[1], y - a[2])
                     for x, y, a in zip(log.x, log.y, auv_log, strict=False)])
    t = t[: dist.size]
    dwins = _windows(starts, turns, t_end, DISTANCE_SETTLE_S)
    moving = np.array([math.hypot(a[1] - b[1], a[2] - b[2]) > 0.05
                       for a, b in zip(auv_log[1:], auv_log[:-1], strict=True)] + [False])
    moving = moving[: dist.size]
    dsel = np.array([d for tt, d, mv in zip(t, dist, moving, strict=True)
                     if mv and _inside(float(tt), dwins)])

    turn_rows = []
    for i, ts in enumerate(turns):
        nxt = turns[i + 1] if i + 1 < len(turns) else t_end
        detect = math.nan
        after = [(tt, e) for tt, e in zip(course_t, course_err, strict=True) if ts <= tt < nxt]
        for j, (tt, _e) in enumerate(after):
            if all(e2 < DETECT_DEG for _t2, e2 in after[j:]):
                detect = tt - ts
                break
        recovery = math.nan
        sel = (t >= ts) & (t < nxt)
        tt_a, dd_a = t[sel], dist[sel]
        for j in range(tt_a.size):
            win = (tt_a >= tt_a[j]) & (tt_a <= tt_a[j] + RECOVER_HOLD_S)
            if tt_a[j] + RECOVER_HOLD_S <= (tt_a[-1] if tt_a.size else 0) and \
                    np.all(dd_a[win] <= RECOVER_M):
                recovery = float(tt_a[j] - ts)
                break
        dmax_turn = float(dd_a.max()) if dd_a.size else math.nan
        turn_rows.append({"t_s": round(ts, 1), "detect_s": detect, "recovery_s": recovery,
                          "distance_max_m": dmax_turn})

    def rms(v: list[float]) -> float:
        return float(np.sqrt(np.mean(np.square(v)))) if v else math.nan

    return {
        "fix_interval_s": fix_interval,
        "fixes": len(fixes),
        "fix_error_rms_m": rms(ferr),
        "track_error_rms_m": rms(terr),
        "course_error_rms_deg": rms(c_sel),
        "turns": turn_rows,
        "distance_median_m": float(np.median(dsel)) if dsel.size else math.nan,
        "distance_p95_m": float(np.percentile(dsel, 95)) if dsel.size else math.nan,
        "distance_max_m": float(dist.max()) if dist.size else math.nan,
        "track_lost_events": sum(1 for tr in tracks if tr.lost),
    }
