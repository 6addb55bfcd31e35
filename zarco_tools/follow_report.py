"""Figures of a simulated follow-the-AUV mission, against the truth.

* ``fix_interval_s``: median time between accepted passive fixes (emission times);
* ``fix_error_rms_m``: accepted fixes vs the AUV's true position at emission;
* ``track_error_rms_m``: the tracker's Kalman filter vs truth;
* ``course_error_rms_deg``: the RLS course vs the true course, on straight legs
  from 30 s after each turn;
* ``turns``: per AUV manoeuvre (turns starting less than ``MERGE_S`` after the
  previous one, such as a lawnmower's two 90° turns at the end of a leg, count
  as one), its net course
  change ``angle_deg`` (positive to starboard) and ``kind`` (``turn`` up to 90°,
  ``uturn`` beyond), ``detect_s`` (from the start of the manoeuvre until the
  course error stays under 10°), ``recovery_s`` (from its start until the last
  time, before the next manoeuvre and up to 60 s after its last turn, that the
  ASV–AUV horizontal distance exceeds 3 m, after which it must stay within 3 m
  for 10 s; 0 if it never exceeded 3 m; None if it did not recover) and
  ``distance_max_m`` (from its start to the next manoeuvre);
* ``distance_median_m``, ``distance_p95_m`` on straight legs from 60 s after
  each manoeuvre (and after the AUV starts moving), ``distance_max_m`` over the
  whole run;
* ``lost_max_s``: the longest time, once the AUV moves, that the ASV was not
  following it (the follow guidance holding: track lost, or the AUV taken for
  still) while the AUV was heard (detected interrogations at most 2.5 s apart);
  ``hold_max_s`` the same whether heard or not, ``fix_gap_max_s`` the longest
  time without an accepted update.

Every figure that cannot be computed (no turn recovered, no straight leg) is
None, never NaN: the report is written as JSON.
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
MERGE_S = 30.0
#: a manoeuvre turning through more than this (deg) is a U-turn
UTURN_DEG = 91.0
#: the AUV counts as heard while its detected interrogations are no further
#: apart than this (s; it pings every 1–2 s, so a longer silence is missed pings)
HEARD_GAP_S = 2.5


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


def manoeuvres(turn_angles: list[tuple[float, float]], t_end: float
               ) -> list[tuple[float, float, float]]:
    """Leg switches (time s, signed angle rad) before ``t_end`` merged into
    manoeuvres: (start s, end s, net angle rad); switches within ``MERGE_S`` of
    the previous one join its manoeuvre."""
    out: list[list[float]] = []
    for t, a in turn_angles:
        if t >= t_end:
            continue
        if out and t - out[-1][1] <= MERGE_S:
            out[-1][1] = t
            out[-1][2] += a
        else:
            out.append([t, t, a])
    return [(a, b, c) for a, b, c in out]


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


def follow_figures(log: TrackLog, counters: dict[str, Any]) -> dict[str, Any]:
    acoustics = counters["acoustics"]
    auv = acoustics.auv
    msgs = counters.get("auv_msgs", [])
    auv_log = counters.get("auv_log", [])
    t_end = log.t[-1] if log.t else 0.0
    man = manoeuvres(auv.turn_angles(), t_end)
    turns = [m[0] for m in man]
    turn_ends = [m[1] for m in man]
    move_start = float(auv.params.start_delay_s)
    # straight legs start after the last turn of each manoeuvre
    starts = [move_start, *turn_ends]

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
    cwins = _windows(starts, turns, t_end, COURSE_SETTLE_S)
    c_sel = [e for t, e in zip(course_t, course_err, strict=True) if _inside(t, cwins)]

    t = np.asarray(log.t)
    dist = np.array([math.hypot(x - a[1], y - a[2])
                     for x, y, a in zip(log.x, log.y, auv_log, strict=False)])
    t = t[: dist.size]
    dwins = _windows(starts, turns, t_end, DISTANCE_SETTLE_S)
    moving = np.array([math.hypot(a[1] - b[1], a[2] - b[2]) > 0.02
                       for a, b in zip(auv_log[1:], auv_log[:-1], strict=True)] + [False])
    moving = moving[: dist.size]
    dsel = np.array([d for tt, d, mv in zip(t, dist, moving, strict=True)
                     if mv and _inside(float(tt), dwins)])

    turn_rows = []
    for i, (ts, te, ang) in enumerate(man):
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
        if tt_a.size:
            # the last time the ASV was more than RECOVER_M away, before the next
            # manoeuvre and up to DISTANCE_SETTLE_S after this one's last turn;
            # from then it must stay within RECOVER_M for RECOVER_HOLD_S (which
            # may run into the next manoeuvre)
            over = (dd_a > RECOVER_M) & (tt_a < te + DISTANCE_SETTLE_S)
            if not over.any():
                recovery = 0.0
            else:
                t_last = float(tt_a[over].max())
                hold = (t > t_last) & (t <= t_last + RECOVER_HOLD_S)
                if t_last + RECOVER_HOLD_S <= t[-1] and np.all(dist[hold] <= RECOVER_M):
                    recovery = t_last - ts
        dmax_turn = float(dd_a.max()) if dd_a.size else math.nan
        deg = math.degrees(ang)
        turn_rows.append({"t_s": round(ts, 1), "angle_deg": round(deg, 1),
                          "kind": "uturn" if abs(deg) > UTURN_DEG else "turn",
                          "detect_s": _num(detect), "recovery_s": _num(recovery),
                          "distance_max_m": _num(dmax_turn),
                          "window_s": round(nxt - ts, 1)})

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

    return finite_or_none({
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
        "fix_gap_max_s": round(gap, 2),
        "hold_max_s": round(hold, 2),
        "lost_max_s": round(lost, 2),
    })
