"""The ASV–AUV distance figures of a follow run, from the distance series alone.

Pure functions of arrays (time s, horizontal distance m, both on the
true-track log's samples) and of the AUV's manoeuvres, so that they are
checked on hand-built series:

* whole-time figures (``distance_median_m``, ``distance_p95_m``,
  ``distance_max_m``): every sample from acquisition (the follow guidance
  first steering by the AUV's track) to the end of the run, turns, losses and
  all;
* settled figures (``settled_distance_median_m``, ``settled_distance_p95_m``):
  only the samples on straight legs from ``SETTLE_S`` after the end of each
  manoeuvre (and after the AUV starts moving) to the start of the next, while
  the AUV moves;
* per manoeuvre: its largest distance (from its start to the next manoeuvre)
  and its recovery: from its start to the last time, before the next
  manoeuvre and up to ``SETTLE_S`` after its end, that the distance exceeds
  ``RECOVER_M``, after which it stays within ``RECOVER_M`` for
  ``RECOVER_HOLD_S`` (0 if it never exceeded ``RECOVER_M``; NaN if it never
  recovered);
* where the whole-time p95 goes (``time_above_4m_s``): the seconds, from
  acquisition, the ASV is further than ``P95_TARGET_M`` from the AUV, by
  phase — ``hover`` (before the AUV starts moving: the approach and the
  hover above it), ``set_off`` (the ``SETTLE_S`` after it starts), each
  manoeuvre's kind (from its start to ``SETTLE_S`` after its end, or the
  next manoeuvre), ``straight`` (the rest: the settled windows) — and
  ``total``, beside ``budget`` (5 % of the followed time: a p95 within
  ``P95_TARGET_M`` needs ``total`` under it).

Percentiles are numpy's default (linear interpolation between order
statistics).  A figure over no sample is NaN (the report writes it as null).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: time after each manoeuvre left out of the settled figures (s)
SETTLE_S = 60.0
#: a turn is recovered once the ASV is within this of the AUV (m) ...
RECOVER_M = 3.0
#: ... for this long (s)
RECOVER_HOLD_S = 10.0
#: leg switches closer than this (s) to the previous one join its manoeuvre
#: (a lawnmower's two 90° turns at the end of a leg are one U-turn)
MERGE_S = 30.0
#: a manoeuvre turning through more than this (deg, as reported: to 0.1°) is a U-turn
UTURN_DEG = 90.0
#: the whole-time p95 target of following (m): the time above it is broken down
P95_TARGET_M = 4.0
#: the phases of the breakdown, in order
PHASES = ("hover", "set_off", "turn", "uturn", "arc", "straight")


@dataclass(frozen=True, slots=True)
class Manoeuvre:
    """A manoeuvre of the AUV: from ``start_s`` to ``end_s`` (sim s), through
    ``angle_rad`` (net, signed, + to starboard); ``arc``: a continuous turn."""

    start_s: float
    end_s: float
    angle_rad: float
    arc: bool = False

    @property
    def kind(self) -> str:
        """``arc`` (a continuous turn), ``uturn`` (beyond 90°) or ``turn``."""
        if self.arc:
            return "arc"
        return "uturn" if round(abs(math.degrees(self.angle_rad)), 1) > UTURN_DEG else "turn"


def merge_manoeuvres(items: list[Manoeuvre], t_end: float) -> list[Manoeuvre]:
    """The AUV's course changes that start before ``t_end``, in time order, with
    leg switches less than ``MERGE_S`` after the previous leg switch's end
    merged into its manoeuvre (net angle); an arc stays one manoeuvre of its
    own and is never merged."""
    out: list[Manoeuvre] = []
    for m in sorted(items, key=lambda m: m.start_s):
        if m.start_s >= t_end:
            continue
        last = out[-1] if out else None
        if (last is not None and not m.arc and not last.arc
                and m.start_s - last.end_s <= MERGE_S):
            out[-1] = Manoeuvre(last.start_s, max(last.end_s, m.end_s),
                                last.angle_rad + m.angle_rad)
        else:
            out.append(m)
    return out


def _pct(d: np.ndarray, q: float) -> float:
    return float(np.percentile(d, q)) if d.size else math.nan


def whole_figures(t: np.ndarray, dist: np.ndarray, acquired_s: float | None
                  ) -> dict[str, float]:
    """Median, 95th percentile and maximum (m) of the distance from
    ``acquired_s`` to the end (NaN when never acquired)."""
    sel = dist[t >= acquired_s] if acquired_s is not None else dist[:0]
    return {"distance_median_m": _pct(sel, 50.0), "distance_p95_m": _pct(sel, 95.0),
            "distance_max_m": float(sel.max()) if sel.size else math.nan}


def settled_windows(move_start_s: float, man: list[Manoeuvre], t_end: float,
                    settle_s: float = SETTLE_S) -> list[tuple[float, float]]:
    """Straight-leg windows [a, b): from ``settle_s`` after the AUV starts
    moving or after a manoeuvre ends, to the start of the next manoeuvre."""
    starts = [move_start_s, *(m.end_s for m in man)]
    stops = [m.start_s for m in man] + [t_end]
    return [(s + settle_s, e) for s, e in zip(starts, stops, strict=True)
            if s + settle_s < e]


def settled_figures(t: np.ndarray, dist: np.ndarray, moving: np.ndarray,
                    acquired_s: float | None, windows: list[tuple[float, float]]
                    ) -> dict[str, float]:
    """Median and 95th percentile (m) over the samples inside ``windows``, from
    ``acquired_s`` on, where the AUV ``moving``."""
    sel = np.zeros(t.size, dtype=bool)
    for a, b in windows:
        sel |= (t >= a) & (t < b)
    sel &= moving
    sel &= (t >= acquired_s) if acquired_s is not None else False
    d = dist[sel]
    return {"settled_distance_median_m": _pct(d, 50.0),
            "settled_distance_p95_m": _pct(d, 95.0)}


def recovery_s(t: np.ndarray, dist: np.ndarray, start_s: float, end_s: float,
               next_s: float) -> float:
    """Recovery of the manoeuvre ``start_s``–``end_s`` followed by the next one
    at ``next_s`` (s from its start; 0 if the distance never exceeded
    ``RECOVER_M``; NaN if it never recovered).  The hold after the last
    excursion may run into the next manoeuvre but not past the end of the
    series."""
    sel = (t >= start_s) & (t < next_s)
    tt, dd = t[sel], dist[sel]
    if not tt.size:
        return math.nan
    over = (dd > RECOVER_M) & (tt < end_s + SETTLE_S)
    if not over.any():
        return 0.0
    t_last = float(tt[over].max())
    if t_last + RECOVER_HOLD_S > t[-1]:
        return math.nan
    hold = (t > t_last) & (t <= t_last + RECOVER_HOLD_S)
    return t_last - start_s if bool(np.all(dist[hold] <= RECOVER_M)) else math.nan


def manoeuvre_rows(t: np.ndarray, dist: np.ndarray, man: list[Manoeuvre], t_end: float
                   ) -> list[dict[str, float | str]]:
    """Per manoeuvre: ``t_s`` (start), ``end_s``, ``angle_deg`` (net, + to
    starboard), ``kind``, ``distance_max_m`` (from its start to the next
    manoeuvre), ``recovery_s``, ``window_s`` (to the next manoeuvre or the
    end)."""
    rows: list[dict[str, float | str]] = []
    for i, m in enumerate(man):
        nxt = man[i + 1].start_s if i + 1 < len(man) else t_end
        sel = (t >= m.start_s) & (t < nxt)
        rows.append({"t_s": round(m.start_s, 1), "end_s": round(m.end_s, 1),
                     "angle_deg": round(math.degrees(m.angle_rad), 1), "kind": m.kind,
                     "distance_max_m": float(dist[sel].max()) if sel.any() else math.nan,
                     "recovery_s": recovery_s(t, dist, m.start_s, m.end_s, nxt),
                     "window_s": round(nxt - m.start_s, 1)})
    return rows


def time_above_by_phase(t: np.ndarray, dist: np.ndarray, acquired_s: float | None,
                        move_start_s: float, man: list[Manoeuvre]) -> dict[str, float]:
    """Seconds (from ``acquired_s``) the distance exceeds ``P95_TARGET_M``, by
    phase (the module's docstring), with ``total`` and ``budget`` (s): each
    sample counts its interval to the next (the last one the median
    interval).  Empty when never acquired."""
    if acquired_s is None or t.size < 2:
        return {}
    dt = np.diff(t, append=t[-1] + float(np.median(np.diff(t))))
    phase = np.full(t.size, "straight", dtype=object)
    for i, m in enumerate(man):
        nxt = man[i + 1].start_s if i + 1 < len(man) else math.inf
        phase[(t >= m.start_s) & (t < min(m.end_s + SETTLE_S, nxt))] = m.kind
    phase[(t >= move_start_s) & (t < move_start_s + SETTLE_S)] = "set_off"
    phase[t < move_start_s] = "hover"
    sel = t >= acquired_s
    above = sel & (dist > P95_TARGET_M)
    out = {p: round(float(dt[above & (phase == p)].sum()), 2) for p in PHASES}
    out["total"] = round(float(dt[above].sum()), 2)
    out["budget"] = round(0.05 * float(dt[sel].sum()), 2)
    return out
