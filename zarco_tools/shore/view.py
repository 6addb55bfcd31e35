"""The ``zarco shore status`` view: one row per vessel, and their latest events."""

from __future__ import annotations

import time
from typing import Any

from zarco_tools.shore.client import VesselView

#: telemetry older than this (s) shows the link as stale
STALE_S = 2.0


def _f(v: Any, fmt: str, unit: str = "") -> str:
    return "—" if v is None else f"{v:{fmt}}{unit}"


def _devices(health: dict[str, Any]) -> str:
    devs = health.get("devices") or {}
    bad = [f"{n}:{d.get('state')}" for n, d in sorted(devs.items()) if d.get("state") != "ok"]
    return "all ok" if devs and not bad else (" ".join(bad) if bad else "—")


def row(v: VesselView, now: float | None = None) -> dict[str, str]:
    """The columns of one vessel, as text."""
    s, a = v.state, v.auv
    now = time.monotonic() if now is None else now
    age = v.age_s("state", now)
    leg = s.get("leg")
    legs = s.get("legs") or 0
    auv = "—"
    if a:
        auv = f"{_f(a.get('distance_m'), '.1f', ' m')} ({a.get('status', '?')})"
        if (v.age_s("auv", now) or 0.0) > 30.0:
            auv += " old"
    return {
        "vessel": v.name,
        "mode": str(s.get("mode", "?")),
        "armed": ("—" if not isinstance(s.get("armed"), bool)
                  else "ARMED" if s["armed"] else "disarmed"),
        "position": (f"{s['lat_deg']:.6f}, {s['lon_deg']:.6f}"
                     if s.get("lat_deg") is not None and s.get("lon_deg") is not None else "—"),
        "fix": str(s.get("fix", "—")),
        "hdg/sog": (_f(s.get("heading_deg"), "5.1f", "°") + " "
                    + _f(s.get("speed_mps"), ".2f", " m/s")),
        "leg": f"{leg + 1}/{legs}" if isinstance(leg, int) and legs else "—",
        "xtrack": _f(s.get("xtrack_m"), '+.2f', " m"),
        "u1/u2": f"{_f(s.get('u1'), '.0f')}/{_f(s.get('u2'), '.0f')}",
        "auv": auv,
        "devices": _devices(v.health),
        "failsafes": ", ".join(s.get("failsafes") or []) or "none",
        "link": ("no state" if age is None
                 else f"{age:.1f} s" + (" STALE" if age > STALE_S else "")),
    }


COLUMNS = ("vessel", "mode", "armed", "position", "fix", "hdg/sog", "leg", "xtrack", "u1/u2", "auv",
           "devices", "failsafes", "link")


def shown_events(v: VesselView, n: int) -> list[dict[str, Any]]:
    """The latest ``n`` events worth a line: not every accepted thrust (teleop
    renews it several times a second)."""
    evs = [e for e in v.events if not (e.get("kind") == "ack"
                                       and str(e.get("text", "")).startswith("thrust from")
                                       and str(e.get("text", "")).endswith("accepted"))]
    return evs[-n:] if n > 0 else []


def plain(vessels: dict[str, VesselView], events: int = 3) -> str:
    """The view as plain text (a table and each vessel's latest events)."""
    rows = [row(v) for _, v in sorted(vessels.items())]
    if not rows:
        return "no vessel heard yet"
    width = {c: max(len(c), *(len(r[c]) for r in rows)) for c in COLUMNS}
    lines = ["  ".join(c.ljust(width[c]) for c in COLUMNS)]
    lines += ["  ".join(r[c].ljust(width[c]) for c in COLUMNS) for r in rows]
    for name, v in sorted(vessels.items()):
        for e in shown_events(v, events):
            lines.append(f"  {name} {_clock(e.get('t'))} {e.get('kind')}: {e.get('text')}")
    return "\n".join(lines)


def _clock(t: Any) -> str:
    if not isinstance(t, (int, float)):
        return "--:--:--"
    return time.strftime("%H:%M:%S", time.gmtime(t))


def rich_view(vessels: dict[str, VesselView], endpoints: list[str], events: int = 5) -> Any:
    """The view as a rich renderable (table and events)."""
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    table = Table(title="zarco shore — " + ", ".join(endpoints), expand=True)
    for c in COLUMNS:
        table.add_column(c, no_wrap=c in ("vessel", "mode", "armed", "position"))
    for _, v in sorted(vessels.items()):
        r = row(v)
        style = ""
        if "STALE" in r["link"] or r["link"] == "no state":
            style = "dim"
        elif r["failsafes"] != "none":
            style = "bold red"
        table.add_row(*(r[c] for c in COLUMNS), style=style)
    parts: list[Any] = [table]
    if not vessels:
        parts.append(Text("waiting for telemetry…"))
    for name, v in sorted(vessels.items()):
        for e in shown_events(v, events):
            parts.append(Text(f"{name} {_clock(e.get('t'))} {e.get('kind')}: {e.get('text')}",
                              style="yellow" if e.get("kind") == "failsafe" else ""))
    return Group(*parts)
