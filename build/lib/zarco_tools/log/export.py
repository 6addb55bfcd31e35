"""``zarco log export``: one topic of a recording as CSV (or JSON lines)."""

from __future__ import annotations

import csv
import json
from typing import IO, Any

from zarco_tools.log.reader import Recording, iter_messages


def flatten(d: Any, prefix: str = "", out: dict[str, Any] | None = None) -> dict[str, Any]:
    """Nested objects as ``a.b`` columns, arrays of numbers as ``a.0``, ``a.1``, ...;
    other arrays as JSON text."""
    out = {} if out is None else out
    if isinstance(d, dict):
        for k, v in d.items():
            flatten(v, f"{prefix}{k}." if isinstance(v, dict) else f"{prefix}{k}", out)
    elif isinstance(d, list) and all(isinstance(x, (int, float)) or x is None for x in d):
        for i, x in enumerate(d):
            out[f"{prefix}.{i}"] = x
    elif isinstance(d, list):
        out[prefix] = json.dumps(d)
    else:
        out[prefix.rstrip(".")] = d
    return out


def export(rec: Recording, topic: str, out: IO[str], fmt: str = "csv") -> int:
    """Write ``topic``'s messages to ``out``; returns how many.  The first column,
    ``log_utc_s``, is when the recorder took the message (UTC seconds)."""
    rows: list[dict[str, Any]] = []
    cols: dict[str, None] = {"log_utc_s": None}
    for m in iter_messages(rec, {topic}):
        if fmt == "jsonl":
            out.write(json.dumps({"log_utc_s": m.log_ns / 1e9, **m.json()}) + "\n")
            rows.append({})
            continue
        row = {"log_utc_s": f"{m.log_ns / 1e9:.6f}", **flatten(m.json())}
        for k in row:
            cols.setdefault(k, None)
        rows.append(row)
    if fmt == "csv":
        w = csv.DictWriter(out, fieldnames=list(cols), lineterminator="\n")
        w.writeheader()
        for row in rows:
            w.writerow(row)
    return len(rows)
