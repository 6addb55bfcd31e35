"""A follow mission's report against its targets.

Per mission, each check either passes, fails (with short reasons) or is
exempt (physics or observability forbids it; the reason carries the figure):

* ``median``, ``p95``: the whole-time distance median and p95 (from
  acquisition to the end) within ``distance_median_m``/``distance_p95_m``, or
  ``survey_distance_*`` when the beacons' true positions are off their
  surveyed ones (a bias the tracker may not remove costs about that much);
* ``turn``: every turn up to 90° peaks within ``turn_max_m`` and recovers
  (within 3 m for 10 s) within ``turn_recovery_s``;
* ``uturn``: every U-turn within ``uturn_max_m`` and ``uturn_recovery_s``
  (``plan_uturn_*`` when the runtime has the AUV's plan and the AUV keeps to
  it);
* ``arc``: every continuous turn peaks within ``arc_max_m`` and is recovered;
* ``lost``: never without a usable track for more than ``lost_max_s`` while
  the AUV is heard;
* ``sound_speed``: the tracker's sound speed within ``sound_speed_error_pct``
  of the truth from 300 s after acquisition (exempt with two beacons, where it
  is not observable, when the configured value is off; and when the surveyed
  network's own scale is off the true one's by more than that — timings
  cannot tell a larger network with faster sound:
  :func:`~zarco_tools.campaign.physics.survey_scale_pct`);
* ``json``: the report is valid JSON (no NaN).

A mission whose least closing speed (:mod:`zarco_tools.campaign.physics`) is
≤ 0 is exempt from the distance and turn checks it fails: no boat could do
it, and the mission is left out of "every target" (``left_out``).  The
sound speed's exemption (not observable) drops that check alone: the
mission is judged on the others.
"""

from __future__ import annotations

import json
import math
from typing import Any

from zarco_tools.campaign.draw import Judgement

TARGETS = (
    "distance_median_m", "distance_p95_m", "survey_distance_median_m",
    "survey_distance_p95_m", "turn_max_m", "turn_recovery_s", "uturn_max_m",
    "uturn_recovery_s", "plan_uturn_max_m", "plan_uturn_recovery_s", "arc_max_m",
    "lost_max_s", "sound_speed_error_pct")
#: the checks, in the tables' order
CHECKS = ("median", "p95", "turn", "uturn", "arc", "lost", "sound_speed", "json")
#: checks physics can forbid (closing speed ≤ 0)
PHYSICS = ("median", "p95", "turn", "uturn", "arc")
#: an unrecovered manoeuvre counts this many times its target in the severity
UNRECOVERED = 3.0


def _r(v: Any, nd: int = 2) -> Any:
    return round(v, nd) if isinstance(v, (int, float)) else v


def turn_limits(tg: dict[str, float], kind: str, planned: bool) -> tuple[float, float | None]:
    """(peak m, recovery s or None: only recovered) of a manoeuvre's kind."""
    if kind == "turn":
        return tg["turn_max_m"], tg["turn_recovery_s"]
    if kind == "uturn":
        if planned:
            return tg["plan_uturn_max_m"], tg["plan_uturn_recovery_s"]
        return tg["uturn_max_m"], tg["uturn_recovery_s"]
    return tg["arc_max_m"], None


def judge_follow(tg: dict[str, float], factors: dict[str, Any], report: dict[str, Any]
                 ) -> Judgement:
    fails: dict[str, list[str]] = {}
    #: (check, figure / target)
    ratios: list[tuple[str, float]] = []

    def fail(key: str, why: str) -> None:
        fails.setdefault(key, []).append(why)

    survey = factors.get("calibration") in ("survey", "all")
    med_t = tg["survey_distance_median_m" if survey else "distance_median_m"]
    p95_t = tg["survey_distance_p95_m" if survey else "distance_p95_m"]
    med, p95 = report.get("distance_median_m"), report.get("distance_p95_m")
    if med is None or med > med_t:
        fail("median", f"median {_r(med)} m > {med_t:g}")
    if p95 is None or p95 > p95_t:
        fail("p95", f"p95 {_r(p95)} m > {p95_t:g}")
    ratios += [("median", (med if med is not None else math.inf) / med_t),
               ("p95", (p95 if p95 is not None else math.inf) / p95_t)]
    planned = factors.get("plan") == "plan"
    turns_ok: list[bool] = []
    for tr in report.get("turns") or []:
        kind = tr["kind"]
        mx, rec_t = turn_limits(tg, kind, planned)
        d, rec = tr.get("distance_max_m"), tr.get("recovery_s")
        bad = d is None or d > mx or rec is None or (rec_t is not None and rec > rec_t)
        turns_ok.append(not bad)
        if bad:
            fail(kind, f"{tr['angle_deg']:+.0f}° at {tr['t_s']:.0f} s: peak {_r(d, 1)} m, "
                       f"recovery {_r(rec, 1) if rec is not None else 'never'}"
                       f"{' s' if rec is not None else ''}")
        ratios.append((kind, (d if d is not None else math.inf) / mx))
        if rec is None:
            ratios.append((kind, UNRECOVERED))
        elif rec_t is not None:
            ratios.append((kind, rec / rec_t))
    lost = report.get("lost_max_s")
    if lost is None or lost > tg["lost_max_s"]:
        fail("lost", f"{lost} s without a usable track")
    ratios.append(("lost", (lost if lost is not None else math.inf) / tg["lost_max_s"]))
    exempt: dict[str, str] = {}
    err = report.get("sound_speed_error_max_pct")
    c_off = abs(float(factors.get("sound_speed_error_pct") or 0.0))
    if err is not None:
        if err > tg["sound_speed_error_pct"]:
            scale = float(factors.get("survey_scale_pct") or 0.0)
            if factors.get("beacons") == 2 and c_off > tg["sound_speed_error_pct"]:
                exempt["sound_speed"] = (f"not observable with 2 beacons: error {err:.2f} % "
                                         f"(configured {c_off:.2f} % off)")
            elif abs(scale) > tg["sound_speed_error_pct"]:
                exempt["sound_speed"] = (f"not observable: the surveyed network is "
                                         f"{scale:+.2f} % the true one's size: error "
                                         f"{err:.2f} %")
            else:
                fail("sound_speed", f"error {err:.2f} % > {tg['sound_speed_error_pct']:g} % "
                                    "from 300 s after acquisition")
        ratios.append(("sound_speed", err / tg["sound_speed_error_pct"]))
    elif report.get("acquired_s") is None:
        fail("sound_speed", "never acquired")
    try:
        json.dumps(report, allow_nan=False)
    except ValueError:
        fail("json", "NaN in the report")
    closing = factors.get("closing_mps")
    if isinstance(closing, (int, float)) and closing <= 0.0:
        for key in PHYSICS:
            if key in fails:
                exempt[key] = (f"closing speed {closing:+.2f} m/s: " + "; ".join(fails.pop(key)))
    if "json" in fails:
        ratios.append(("json", 99.0))
    # how far from the targets, over the checks that are not exempt
    severity = max([min(r, 99.0) for k, r in ratios if k not in exempt] or [0.0])
    return Judgement(fails, exempt, round(severity, 3), tuple(turns_ok),
                     left_out=any(k in exempt for k in PHYSICS))
