"""``zarco log plot``: the figures of ``zarco sim --plot`` drawn from a recording.

Lines missions: the track over the planned lines and the cross-track error
(paper Figs. 4, 5); follow missions: the tracks, the AUV's estimated velocity
and course and the ASV–AUV distance (Figs. 7, 8, 9).  A simulation's
recording carries the simulator's truth (``/SimTruth``) and gives exactly the
figures ``zarco sim --plot`` drew; a vessel's recording gives them from what
the vessel knew: its estimate (NavState, 10 Hz) and the AUV's filtered track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zarco_core.auv_messages import AuvFix, AuvTrack, TrackFlags
from zarco_runtime.guidance.mission import Leg
from zarco_runtime.supervision.supervisor import mission_from_json
from zarco_tools.log.reader import Recording, iter_messages, rebuild
from zarco_tools.sim_report import TrackLog, line_figures

#: rate of the track samples taken from NavState when there is no truth (Hz)
TRACK_HZ = 10.0
TOPICS = {"/SimTruth", "/NavState", "/GuidanceStatus", "/ThrusterCommand", "/Directive",
          "/AuvFix", "/AuvTrack"}


@dataclass(slots=True)
class Figures:
    kind: str
    log: TrackLog
    legs: list[Leg]
    extra: dict[str, Any] = field(default_factory=dict)
    truth: bool = False


def _legs(d: dict[str, Any] | None) -> list[Leg]:
    if not d or d.get("kind") != "lines":
        return []
    legs = d.get("legs", [])
    if legs and isinstance(legs[0], dict):  # a Directive's mission: Leg objects
        return [Leg(**lg) for lg in legs]
    return list(mission_from_json(d).legs)


def collect(rec: Recording) -> Figures:
    """Track, legs and AUV messages of a recording, as ``zarco sim`` keeps them."""
    boot = rec.boot.get("mission")
    kind = "follow" if boot and boot.get("kind") == "follow" else "lines"
    legs = _legs(boot)
    truth = TrackLog()
    est = TrackLog()
    auv_truth: list[tuple[float, float, float, float]] = []
    auv_est: list[tuple[float, float, float, float]] = []
    msgs: list[Any] = []
    leg, u1, u2 = 0, 0.0, 0.0
    t0 = rec.t0
    next_t = -math.inf
    for m in iter_messages(rec, TOPICS):
        d = m.json()
        topic = m.topic
        if topic == "/SimTruth":
            truth.add(d["t"], d["x_m"], d["y_m"], d["psi_rad"], d["leg"], d["u1"], d["u2"])
            if d.get("auv_x_m") is not None:
                auv_truth.append((d["t"], d["auv_x_m"], d["auv_y_m"], d["auv_psi_rad"]))
        elif topic == "/GuidanceStatus":
            leg = int(d["leg"])
        elif topic == "/ThrusterCommand":
            u1, u2 = float(d["u1"]), float(d["u2"])
        elif topic == "/NavState":
            if d["pos_valid"] and d["t"] >= next_t:
                next_t = d["t"] + 1.0 / TRACK_HZ
                est.add(d["t"] - t0, d["x_m"], d["y_m"], d["psi_rad"], leg, u1, u2)
        elif topic == "/Directive":
            if d.get("mode") == "follow":
                kind = "follow"
            elif d.get("mode") == "lines" and d.get("mission"):
                legs = _legs(d["mission"]) or legs
        elif topic == "/AuvFix":
            msgs.append(rebuild(AuvFix, d))
        elif topic == "/AuvTrack":
            tr = rebuild(AuvTrack, d)
            msgs.append(tr)
            if tr.flags & TrackFlags.INITIALISED and not tr.lost:
                auv_est.append((tr.t - t0, tr.kf_x_m, tr.kf_y_m, tr.psi_auv_rad))
    if msgs and kind != "follow" and not legs:
        kind = "follow"
    if truth.t:
        return Figures(kind, truth, legs, {"auv_log": auv_truth, "auv_msgs": msgs}, True)
    # the AUV's filtered position at the track samples' times (Fig. 9's distance)
    auv_log: list[tuple[float, float, float, float]] = []
    j = 0
    for t in est.t:
        while j + 1 < len(auv_est) and auv_est[j + 1][0] <= t:
            j += 1
        if auv_est and auv_est[j][0] <= t:
            auv_log.append((t, *auv_est[j][1:]))
        else:
            auv_log.append((t, math.nan, math.nan, math.nan))
    shifted = [_shift(x, t0) for x in msgs]
    return Figures(kind, est, legs, {"auv_log": auv_log, "auv_msgs": shifted}, False)


def _shift(m: Any, t0: float) -> Any:
    m.t -= t0
    return m


def plot_recording(rec: Recording, out: str | Path) -> Figures:
    """Draw the recording's figures into ``out`` (PNG)."""
    from zarco_tools.plot import plot_follow, plot_lines

    f = collect(rec)
    name = Path(rec.paths[0]).name
    src = "simulator's truth" if f.truth else "vessel's estimate"
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    if f.kind == "follow":
        plot_follow(out, f.log, f.extra, f"{name} ({src})", truth=f.truth)
    else:
        rms = line_figures(f.log, f.legs)["xtrack_rms_m"] if f.legs else math.nan
        plot_lines(out, f.log, f.legs, f"{name} ({src}): RMS {rms:.3f} m", truth=f.truth)
    return f
