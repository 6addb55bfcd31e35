"""A campaign's output directory: ``campaign.json`` (which campaign: spec, its
digest, seed, the ``--set`` overrides, the ``--choice`` weights) and
``results.jsonl`` (one JSON object per mission, appended and flushed as each
arrives).

Resuming: the missions already in ``results.jsonl`` are not run again; a
line cut short by a kill (the last one, without its newline) is dropped and
its mission run again.  A directory that holds another campaign (another
spec, seed, overrides or choices) is refused rather than mixed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from zarco_core.config import ConfigError

HEADER = "campaign.json"
RESULTS = "results.jsonl"
#: the header's keys that must match to resume
SAME = ("name", "kind", "digest", "seed", "sets", "choices")


def read_results(path: str | Path) -> tuple[dict[int, dict[str, Any]], int]:
    """The missions of a results file by index (the first record of an index
    wins) and how many lines were dropped (cut short or not JSON)."""
    out: dict[int, dict[str, Any]] = {}
    bad = 0
    p = Path(path)
    if not p.exists():
        return out, 0
    with p.open("rb") as fh:
        for raw in fh:
            if not raw.endswith(b"\n"):
                bad += 1
                continue
            try:
                rec = json.loads(raw)
                k = int(rec["index"])
            except (ValueError, KeyError, TypeError):
                bad += 1
                continue
            out.setdefault(k, rec)
    return out, bad


def load_dir(path: str | Path) -> tuple[dict[str, Any], dict[int, dict[str, Any]]]:
    """(header, missions by index) of a campaign's output directory or of a
    results file beside its header."""
    p = Path(path)
    d = p if p.is_dir() else p.parent
    res = p / RESULTS if p.is_dir() else p
    if not res.exists():
        raise ConfigError(str(path), "", f"no {RESULTS} here: not a campaign's output")
    header: dict[str, Any] = {}
    if (d / HEADER).exists():
        header = json.loads((d / HEADER).read_text())
    return header, read_results(res)[0]


class ResultsDir:
    """Appends a campaign's results as they arrive; knows what is done."""

    def __init__(self, path: str | Path, header: dict[str, Any]) -> None:
        self.dir = Path(path)
        self.header = header
        self.done: dict[int, dict[str, Any]] = {}
        self.dropped = 0

    def open(self) -> None:
        """Create the directory or check it holds this campaign; read what is
        done; rewrite the results without a line cut short."""
        self.dir.mkdir(parents=True, exist_ok=True)
        hp = self.dir / HEADER
        if hp.exists():
            old = json.loads(hp.read_text())
            diff = [k for k in SAME if old.get(k) != self.header.get(k)]
            if diff:
                key = diff[0]
                raise ConfigError(str(self.dir), key, f"holds another campaign ({key} "
                                  f"{old.get(key)!r}, this run {self.header.get(key)!r}): "
                                  "give another --out")
        tmp = hp.with_suffix(".tmp")
        tmp.write_text(json.dumps(self.header, indent=1) + "\n")
        os.replace(tmp, hp)
        rp = self.dir / RESULTS
        self.done, self.dropped = read_results(rp)
        if self.dropped:
            tmp = rp.with_suffix(".tmp")
            with tmp.open("w") as fh:
                for k in sorted(self.done):
                    fh.write(json.dumps(self.done[k], allow_nan=False) + "\n")
            os.replace(tmp, rp)
        self._fh = rp.open("a")

    def append(self, rec: dict[str, Any]) -> None:
        """Write one mission's record and push it to the disk."""
        self._fh.write(json.dumps(rec, allow_nan=False) + "\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self.done[int(rec["index"])] = rec

    def close(self) -> None:
        fh = getattr(self, "_fh", None)
        if fh is not None:
            fh.close()
