"""A campaign's tables: which missions meet which target, per family and per
drawn category; the missions physics exempts, with their figures; the worst
missions with the ``zarco sim`` command that reproduces each; the spread of
the main figures; where the follow missions' time further than 4 m from
the AUV went (the whole-time p95 target's budget, by phase).

A mission passes a check when the check is neither failed nor exempt.  A
check applies to a mission that has something to judge: a turn check to a
mission with a manoeuvre of that kind, the sound-speed check to one with an
estimate 300 s after acquisition; cells read ``passed/applicable`` with the
exempt missions after them (``+2 exempt``).  "every target" counts the
missions with no failed check (an exempt check is not a miss) among those
physics leaves in (:func:`in_every`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from zarco_tools.campaign.draw import Mission
from zarco_tools.follow_distance import PHASES

#: categorical factors tabulated beside the families (when drawn)
CATEGORIES = ("route", "plan", "calibration", "beacons", "layout")
#: closing-speed classes (m/s) of the follow campaign's table
CLOSING_BINS = ((-9.0, 0.0), (0.0, 0.2), (0.2, 0.4), (0.4, 0.6), (0.6, 9.0))
#: figures whose spread is shown (those present)
SPREAD = ("distance_median_m", "distance_p95_m", "distance_max_m", "settled_distance_median_m",
          "settled_distance_p95_m", "lost_max_s", "sound_speed_error_max_pct",
          "track_error_rms_m", "xtrack_rms_m", "xtrack_p95_m", "hold_distance_p95_m",
          "hold_distance_max_m")
TURN_KINDS = ("turn", "uturn", "arc")


def applies(check: str, rec: dict[str, Any]) -> bool:
    if check in rec.get("fails", {}) or check in rec.get("exempt", {}):
        return True
    fig = rec.get("figures") or {}
    if check in TURN_KINDS:
        return any(t.get("kind") == check for t in fig.get("turns") or [])
    if check == "sound_speed":
        return fig.get("sound_speed_error_max_pct") is not None
    return "crash" not in rec.get("fails", {})


def in_every(rec: dict[str, Any]) -> bool:
    """Whether the mission counts in "every target": not left out by its
    judge (physics forbids what it is for).  A record from before the judges
    said so leaves out every mission with an exemption, as it was counted
    then."""
    return not rec.get("left_out", bool(rec.get("exempt")))


def _cell(recs: list[dict[str, Any]], check: str) -> dict[str, int]:
    app = [r for r in recs if applies(check, r)]
    ex = [r for r in app if check in r.get("exempt", {})]
    failed = [r for r in app if check in r.get("fails", {})]
    return {"applicable": len(app) - len(ex), "passed": len(app) - len(ex) - len(failed),
            "exempt": len(ex)}


def _group(recs: list[dict[str, Any]], checks: tuple[str, ...]) -> dict[str, Any]:
    judged = [r for r in recs if in_every(r)]
    return {"missions": len(recs),
            "every_target": {"applicable": len(judged),
                             "passed": sum(1 for r in judged if not r.get("fails")),
                             "exempt": len(recs) - len(judged)},
            "checks": {c: _cell(recs, c) for c in (*checks, "crash")}}


def _dist(vals: list[Any]) -> dict[str, float] | None:
    v = [float(x) for x in vals if isinstance(x, (int, float)) and math.isfinite(x)]
    if not v:
        return None
    a = np.asarray(v)
    return {"p50": round(float(np.median(a)), 3), "p90": round(float(np.percentile(a, 90)), 3),
            "max": round(float(a.max()), 3), "n": len(v)}


def _closing_class(c: float) -> str:
    for lo, hi in CLOSING_BINS:
        if lo <= c < hi:
            return f"{lo:+.1f}…{hi:+.1f}" if abs(hi) < 9 and abs(lo) < 9 else (
                f"< {hi:+.1f}" if lo < -8 else f"≥ {lo:+.1f}")
    return "?"


def time_above(recs: list[dict[str, Any]]) -> dict[str, Any]:
    """Where the whole-time p95 goes, over the missions whose report has it: the
    seconds further than 4 m from the AUV by phase (``time_above_4m_s`` of
    :mod:`zarco_tools.follow_report`) summed, their total, the summed budget
    (5 % of each followed time) and how many missions spent more than theirs;
    empty when no mission has it."""
    rows = [a for r in recs if (a := (r.get("figures") or {}).get("time_above_4m_s"))]
    if not rows:
        return {}
    out: dict[str, Any] = {p: round(sum(float(a.get(p, 0.0)) for a in rows), 1)
                           for p in (*PHASES, "total", "budget")}
    out["missions"] = len(rows)
    out["over_budget"] = sum(1 for a in rows if a["total"] > a["budget"])
    return out


def summarise(records: list[dict[str, Any]], checks: tuple[str, ...], scenario_file: str,
              sets: list[str], worst: int = 5) -> dict[str, Any]:
    """The campaign's tables as data (see the module's docstring)."""
    recs = sorted(records, key=lambda r: r["index"])
    families = sorted({r["family"] for r in recs})
    by: dict[str, dict[str, Any]] = {}
    for cat in CATEGORIES:
        vals = sorted({str(r["factors"].get(cat)) for r in recs if cat in r["factors"]})
        if len(vals) > 1:
            by[cat] = {v: _group([r for r in recs if str(r["factors"].get(cat)) == v], checks)
                       for v in vals}
    if any("closing_mps" in r["factors"] for r in recs):
        classes = [_closing_class(lo) for lo, _hi in CLOSING_BINS]
        by["closing speed (m/s)"] = {
            c: _group([r for r in recs if "closing_mps" in r["factors"]
                       and _closing_class(r["factors"]["closing_mps"]) == c], checks)
            for c in classes}
    turns: dict[str, dict[str, int]] = {}
    for kind in TURN_KINDS:
        rows = [(t, ok) for r in recs
                for t, ok in zip((r.get("figures") or {}).get("turns") or [],
                                 r.get("turns_ok") or [], strict=False)
                if t.get("kind") == kind]
        if rows:
            turns[kind] = {"n": len(rows), "passed": sum(1 for _t, ok in rows if ok),
                           "unrecovered": sum(1 for t, _ok in rows
                                              if t.get("recovery_s") is None)}
    exempt = [{"index": r["index"], "family": r["family"], "checks": r["exempt"],
               "closing_mps": r["factors"].get("closing_mps")} for r in recs if r.get("exempt")]
    ranked = sorted((r for r in recs if r.get("fails")), key=lambda r: -r["severity"])
    worst_rows = [{"index": r["index"], "family": r["family"], "severity": r["severity"],
                   "fails": r["fails"],
                   "command": Mission(r["index"], r["family"], r["scenario_seed"],
                                      r["overrides"]).command(scenario_file, sets)}
                  for r in ranked[:worst]]
    spread = {k: d for k in SPREAD
              if (d := _dist([(r.get("figures") or {}).get(k) for r in recs])) is not None}
    spread["severity"] = _dist([r["severity"] for r in recs]) or {}
    cpu = [float(r["cpu_s"]) for r in recs if r.get("cpu_s")]
    return {"missions": len(recs), "checks": list(checks), "all": _group(recs, checks),
            "by_family": {f: _group([r for r in recs if r["family"] == f], checks)
                          for f in families},
            "by": by, "turns": turns, "exempt": exempt, "worst": worst_rows,
            "spread": spread, "time_above_4m_s": time_above(recs),
            "cpu_s_per_mission": round(float(np.mean(cpu)), 2) if cpu else None}


def _fmt_cell(c: dict[str, int]) -> str:
    if c["applicable"] == 0 and c["exempt"] == 0:
        return "—"
    s = f"{c['passed']}/{c['applicable']}"
    return s + (f" +{c['exempt']}ex" if c["exempt"] else "")


def _table(title: str, groups: dict[str, dict[str, Any]], checks: list[str]) -> list[str]:
    cols = [*checks, "every target"]
    w0 = max(12, *(len(k) for k in groups)) + 1
    widths = [max(len(c), 11) + 1 for c in cols]
    out = [title, f"{'':<{w0}}{'n':>4}  " + "".join(f"{c:>{w}}" for c, w in
                                                     zip(cols, widths, strict=True))]
    for name, g in groups.items():
        cells = [_fmt_cell(g["checks"][c]) for c in checks] + [_fmt_cell(g["every_target"])]
        out.append(f"{name:<{w0}}{g['missions']:>4}  " + "".join(
            f"{c:>{w}}" for c, w in zip(cells, widths, strict=True)))
    return out


def format_summary(s: dict[str, Any]) -> str:
    """The tables as text, for the terminal."""
    checks = list(s["checks"])
    if any(g["checks"]["crash"]["applicable"] != g["checks"]["crash"]["passed"]
           for g in [s["all"]]):
        checks.append("crash")
    lines = _table("pass table: missions within each target, per family "
                   "(passed/applicable; +N ex: exempt, physics forbids)",
                   {**s["by_family"], "all": s["all"]}, checks)
    for cat, groups in s["by"].items():
        lines += ["", *_table(f"by {cat}", groups, checks)]
    if s["turns"]:
        lines += ["", "manoeuvres within their targets: " + ", ".join(
            f"{k} {v['passed']}/{v['n']} ({v['unrecovered']} never recovered)"
            for k, v in s["turns"].items())]
    if s["exempt"]:
        lines += ["", "exempt (physics or observability forbids the target; not counted "
                      "as misses):"]
        for e in s["exempt"]:
            for check, why in e["checks"].items():
                lines.append(f"  m{e['index']:04d} {e['family']}: {check}: {why}")
    above = s.get("time_above_4m_s") or {}
    if above:
        tot = above["total"] or 1.0
        lines += ["", f"further than 4 m from the AUV: {above['total']:.0f} s over "
                      f"{above['missions']} missions ({above['over_budget']} over the 5 % a "
                      f"p95 within 4 m allows, {above['budget']:.0f} s together): " + ", ".join(
                          f"{p.replace('_', '-')} {above[p]:.0f} s ({100.0 * above[p] / tot:.0f} %)"
                          for p in PHASES if above[p])]
    if s["spread"]:
        lines += ["", "spread over the missions (p50 / p90 / max):"]
        for k, d in s["spread"].items():
            if d:
                lines.append(f"  {k:<28} {d['p50']:9.3f} {d['p90']:9.3f} {d['max']:9.3f}"
                             f"  (n={d['n']})")
    if s["worst"]:
        lines += ["", "worst missions (severity: the largest figure/target ratio):"]
        for w in s["worst"]:
            why = "; ".join(f"{k}: {', '.join(v)}" for k, v in sorted(w["fails"].items()))
            lines += [f"  m{w['index']:04d} {w['family']} severity {w['severity']}: {why}",
                      f"    {w['command']}"]
    return "\n".join(lines)
