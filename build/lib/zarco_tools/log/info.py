"""``zarco log info``: what a recording holds: duration, topics, counts, gaps,
faults and mode changes."""

from __future__ import annotations

import datetime as dt
import itertools
import statistics
from typing import Any

from zarco_tools.log.reader import Recording, iter_messages

#: a topic's silence counts as a gap when longer than this many median periods...
GAP_PERIODS = 5.0
#: ...and than this (s)
GAP_MIN_S = 1.0
#: event kinds listed as faults
FAULT_KINDS = ("fault", "failsafe", "component")


def _utc(ns: int) -> str:
    return dt.datetime.fromtimestamp(ns / 1e9, dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")[:-4] \
        + "Z"


def summarize(rec: Recording) -> dict[str, Any]:
    """The figures of ``zarco log info`` (one dict, JSON-ready)."""
    times: dict[str, list[int]] = {}
    faults: list[dict[str, Any]] = []
    modes: list[dict[str, Any]] = []
    first = last = None
    for m in iter_messages(rec):
        times.setdefault(m.topic, []).append(m.log_ns)
        first = m.log_ns if first is None else min(first, m.log_ns)
        last = m.log_ns if last is None else max(last, m.log_ns)
        if m.topic == "/Event":
            e = m.json()
            row = {"utc": _utc(m.log_ns), "t": e.get("t"), "kind": e.get("kind"),
                   "text": e.get("text"), "source": e.get("source")}
            if e.get("kind") == "mode":
                modes.append(row)
            elif e.get("kind") in FAULT_KINDS:
                faults.append(row)
        elif m.topic == "/Fault":
            f = m.json()
            faults.append({"utc": _utc(m.log_ns), "t": f.get("t"), "kind": "fault",
                           "text": f.get("reason"), "source": f.get("source")})
    t0 = first or 0
    topics: dict[str, Any] = {}
    gaps: list[dict[str, Any]] = []
    for topic, ts in sorted(times.items()):
        ts.sort()
        dts = [(b - a) / 1e9 for a, b in itertools.pairwise(ts)]
        med = statistics.median(dts) if dts else 0.0
        span = (ts[-1] - ts[0]) / 1e9
        topics[topic] = {"count": len(ts), "rate_hz": round((len(ts) - 1) / span, 3)
                         if span > 0 else None, "max_gap_s": round(max(dts), 3) if dts else None}
        if len(ts) >= 10:
            limit = max(GAP_MIN_S, GAP_PERIODS * med)
            for a, b in itertools.pairwise(ts):
                if (b - a) / 1e9 > limit:
                    gaps.append({"topic": topic, "from_s": round((a - t0) / 1e9, 3),
                                 "length_s": round((b - a) / 1e9, 3), "utc": _utc(a)})
    meta = rec.metadata
    return {
        "files": rec.paths,
        "finished": all(rec.finished.get(p, False) for p in rec.paths),
        "truncated": rec.truncated,
        "version": meta.get("version"),
        "started_utc": _utc(first) if first else None,
        "ended_utc": _utc(last) if last else None,
        "duration_s": round((last - first) / 1e9, 3) if first and last else 0.0,
        "clock": meta.get("clock"),
        "messages": sum(len(v) for v in times.values()),
        "topics": topics,
        "gaps": sorted(gaps, key=lambda g: -g["length_s"]),
        "faults": faults,
        "mode_changes": modes,
    }


def format_info(s: dict[str, Any], max_rows: int = 20) -> str:
    lines = [f"files       {', '.join(s['files'])}",
             f"written by  zarco {s['version']}  ({s['clock']} clock)",
             f"from        {s['started_utc']}  to {s['ended_utc']}  = {s['duration_s']:.1f} s",
             f"messages    {s['messages']} on {len(s['topics'])} topics; "
             + ("finished" if s["finished"] else
                "not finished (the writer was stopped outright: every complete chunk read)"),
             "", f"{'topic':30s} {'count':>8s} {'rate Hz':>9s} {'max gap s':>10s}"]
    for topic, d in s["topics"].items():
        rate = f"{d['rate_hz']:.2f}" if d["rate_hz"] is not None else "-"
        gap = f"{d['max_gap_s']:.2f}" if d["max_gap_s"] is not None else "-"
        lines.append(f"{topic:30s} {d['count']:8d} {rate:>9s} {gap:>10s}")
    lines += ["", f"gaps ({len(s['gaps'])}; a topic silent > {GAP_MIN_S:g} s and "
              f"> {GAP_PERIODS:g} of its periods):"]
    for g in s["gaps"][:max_rows]:
        lines.append(f"  {g['topic']:28s} at {g['from_s']:9.2f} s  for {g['length_s']:7.2f} s")
    lines += ["", f"mode changes ({len(s['mode_changes'])}):"]
    for e in s["mode_changes"][:max_rows]:
        lines.append(f"  {e['utc']}  {e['text']}")
    lines += ["", f"faults and failsafes ({len(s['faults'])}):"]
    for e in s["faults"][:max_rows]:
        lines.append(f"  {e['utc']}  [{e['kind']}] {e['text']}")
    return "\n".join(lines)
