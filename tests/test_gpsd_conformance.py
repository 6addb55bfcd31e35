"""``zarco decode`` against GPSD on every capture in ``tests/data/gpsd-logs/``.

Each ``*.log.chk`` is GPSD's regression output: every input sentence
followed by the JSON reports GPSD printed after processing it.  The capture
is run through ``zarco decode`` (the CLI, in process) and, sentence by
sentence, compared with what GPSD made of it:

* position and fix class of GGA, RMC, GLL and GNS against the TPV reports
  that sentence determined;
* heading (HDT, THS), magnetic heading (HDM), rate of turn (ROT) and
  pitch/roll (XDR) against the ATT reports.

How a TPV is tied to a sentence.  GPSD merges the sentences of one epoch:
the mode (no fix / 2D / 3D) is set by the last sentence that sets one, the
status (GPS, DGPS, RTK, dead reckoning, ...) is the highest any sentence of
the epoch gave, the position is the last one read.  So a TPV is compared
with the last mode-setting sentence printed before it (GGA, RMC, GLL, GNS;
when that is a GSA or a proprietary sentence the TPV is not compared), and
only when the TPV's time is that sentence's time (a TPV without a time only
when printed directly after it).  The fix class must then equal GPSD's
status when the sentence is the first of its epoch, and may not exceed it
otherwise.  A position is compared to the resolution the sentence carries.

Every TPV with a fix that GPSD tied to a sentence must have been compared:
a sentence GPSD took a fix from and ``zarco decode`` refused fails the test,
unless it is one of the disagreements listed in ``DISAGREEMENTS`` with the
reason.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from zarco_runtime.cli import main

DATA = Path(__file__).parent / "data" / "gpsd-logs"
CAPTURES = sorted(p.name for p in DATA.glob("*.log"))
POSITION_TYPES = ("GGA", "RMC", "GLL", "GNS")
#: the data field holding the time of a position sentence
TIME_FIELD = {"GGA": 0, "RMC": 0, "GNS": 0, "GLL": 4}
#: GPSD TPV status → our fix class (0 unknown and 1 GPS are not printed)
STATUS_FIX = {0: "none", 1: "single", 2: "dgps", 3: "rtk_fixed", 4: "rtk_float", 5: "none",
              6: "none", 7: "none", 8: "none", 9: "single"}
#: our fix classes as GPSD's status numbers (GPSD's merge keeps the highest)
FIX_STATUS = {"single": 1, "dgps": 2, "rtk_fixed": 3, "rtk_float": 4}
#: sentences whose decoding GPSD and we knowingly do not share: (capture,
#: sentence text) → why.  Empty: every disagreement found is explained in
#: the comparisons themselves (see ``compare_fix``).
DISAGREEMENTS: dict[tuple[str, str], str] = {}


@dataclass
class Entry:
    """One input sentence of a .chk and the reports GPSD printed after it."""

    line: str
    reports: list[dict[str, Any]] = field(default_factory=list)
    n: int = 0  # its line number in the .log (0: not an NMEA line)

    @property
    def stype(self) -> str:
        address = self.line[1:].split(",", 1)[0].split("*", 1)[0]
        return address if address.startswith("P") else address[2:]

    @property
    def fields(self) -> list[str]:
        return self.line.split("*", 1)[0].split(",")[1:]

    @property
    def tod(self) -> float | None:
        """Time of day (s) of a position sentence, None if it has none."""
        k = TIME_FIELD.get(self.stype)
        f = self.fields
        if k is None or len(f) <= k or not re.fullmatch(r"\d{6}(\.\d*)?", f[k]):
            return None
        s = f[k]
        return int(s[:2]) * 3600 + int(s[2:4]) * 60 + float(s[4:])

    def of(self, cls: str) -> list[dict[str, Any]]:
        return [r for r in self.reports if r["class"] == cls]


def load_chk(name: str) -> list[Entry]:
    """GPSD's output for ``name``, each NMEA entry with its line number in the log."""
    entries: list[Entry] = []
    for raw in (DATA / f"{name}.chk").read_text(errors="replace").splitlines():
        if raw.startswith("{"):
            if entries:
                entries[-1].reports.append(json.loads(raw))
        elif raw.strip():
            entries.append(Entry(raw.strip()))
    log = [(n, ln.strip()) for n, ln in enumerate(
        (DATA / name).read_text(errors="replace").splitlines(), 1) if ln.startswith(("$", "!"))]
    i = 0
    for e in entries:
        if not e.line.startswith(("$", "!")):
            continue
        while i < len(log) and log[i][1] != e.line:
            i += 1
        assert i < len(log), (name, e.line)
        e.n = log[i][0]
        i += 1
    return entries


def zarco_decode(name: str) -> tuple[dict[int, dict[str, Any]], dict[int, str]]:
    """Run ``zarco decode`` on a capture: accepted sentences and refusal
    reasons, both by input line number."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert main(["decode", str(DATA / name)]) == 0
    ok: dict[int, dict[str, Any]] = {}
    for raw in out.getvalue().splitlines():
        item = json.loads(raw)
        assert item["n"] not in ok  # one sentence per line in these captures
        ok[item["n"]] = item
    refused: dict[int, str] = {}
    for raw in err.getvalue().splitlines():
        m = re.match(r".*?:(\d+): (\w+)", raw)
        assert m is not None, raw
        refused.setdefault(int(m[1]), m[2])
    return ok, refused


def _tod_iso(iso: str) -> float:
    hh, mm, ss = iso.split("T")[1].rstrip("Z").split(":")
    return int(hh) * 3600 + int(mm) * 60 + float(ss)


def _resolution_deg(value: str) -> float:
    """Half a unit of the last decimal of a ``ddmm.mmm`` field, in degrees."""
    decimals = len(value.split(".", 1)[1]) if "." in value else 0
    return 0.5 * 10.0 ** -decimals / 60.0


def _mode_setter(e: Entry) -> bool:
    return e.stype in POSITION_TYPES or e.stype == "GSA" or e.line.startswith("$P")


def attributed_tpvs(entries: list[Entry]) -> list[tuple[int, dict[str, Any]]]:
    """(index of the position sentence, TPV) for every TPV GPSD printed that a
    position sentence determined (see the module docstring)."""
    out = []
    last = -1  # index of the last mode-setting sentence
    for j, e in enumerate(entries):
        if _mode_setter(e):
            last = j
        if last < 0 or entries[last].stype not in POSITION_TYPES:
            continue
        s = entries[last]
        for r in e.of("TPV"):
            if "time" in r:
                if s.tod is None or abs(_tod_iso(r["time"]) - s.tod) > 1e-3:
                    continue
            elif j != last:
                continue
            out.append((last, r))
    return out


#: GPSD's faa_mode(): FAA mode letter → status ('' missing, O/V/N unknown,
#: any other letter GPS)
FAA_STATUS = {"": 0, "O": 0, "V": 0, "N": 0, "D": 2, "E": 5, "F": 4, "M": 7, "P": 2,
              "R": 3, "S": 8}
#: GPSD's GGA quality → status
GGA_STATUS = {0: 0, 1: 1, 2: 2, 3: 9, 4: 3, 5: 4, 6: 5, 7: 7, 8: 8}


def gpsd_status(e: Entry) -> int | None:
    """The status GPSD's driver sets for one position sentence (None: it sets
    none), restated from GPSD's NMEA driver so that the highest status of an
    epoch can be checked against the TPV GPSD printed."""
    f = e.fields + [""] * 14
    if e.stype == "GGA":
        return GGA_STATUS.get(int(f[5])) if f[5].isdigit() else None
    if e.stype == "RMC":
        if f[1] != "A":
            return 0
        has_pos = all(f[2:6])
        mode = f[11] if len(e.fields) >= 12 else ""
        return FAA_STATUS.get(mode, 1) if mode else (1 if has_pos else 0)
    if e.stype == "GLL":
        mode = f[6] if len(e.fields) >= 7 else None
        if f[5] != "A" or mode == "N" or not all(f[0:4]):
            return 0
        return 1 if mode is None else FAA_STATUS.get(mode, 1)
    if e.stype == "GNS":
        if not f[5] or f[5][0] == "N" or f[12] in ("U", "V"):
            return None
        return FAA_STATUS.get(f[5][0], 1)
    return None


def gpsd_fix(e: Entry) -> bool:
    """Whether GPSD's driver takes a 2D/3D fix from one position sentence."""
    f = e.fields + [""] * 14
    if e.stype == "GGA":
        few = e.line[1:3] in ("GP", "GN") and int(f[6] or 0) < 3
        return all(f[1:5]) and not few
    if e.stype == "RMC":
        return f[1] == "A" and all(f[2:6])
    if e.stype == "GLL":
        return f[5] == "A" and f[6] != "N" and all(f[0:4])
    if e.stype == "GNS":
        return bool(f[5]) and f[5][0] != "N" and f[12] not in ("U", "V") and all(f[1:5])
    raise AssertionError(e.line)


def gpsd_class(e: Entry) -> str:
    """Our fix class for what GPSD's driver makes of one position sentence."""
    st = gpsd_status(e)
    return STATUS_FIX[st] if gpsd_fix(e) and st is not None else "none"


def epoch_before(entries: list[Entry], i: int) -> list[Entry] | None:
    """The position sentences of the epoch of ``entries[i]`` up to it, or None
    when a proprietary sentence (whose effect on GPSD's status this test does
    not restate) is among them."""
    tod = entries[i].tod
    out = [entries[i]]
    for e in reversed(entries[:i]):
        if e.stype in POSITION_TYPES:
            if tod is None or e.tod is None or abs(e.tod - tod) > 1e-3:
                break
            out.append(e)
        elif e.line.startswith("$P"):
            return None
    return out


def epoch_tpvs(entries: list[Entry], i: int) -> list[dict[str, Any]]:
    """TPVs with a position of the epoch of ``entries[i]``: printed after it
    and before the next position sentence of another time, with its time."""
    tod = entries[i].tod
    out = []
    for k in range(i, len(entries)):
        e = entries[k]
        if k > i and e.stype in POSITION_TYPES and (
                e.tod is None or tod is None or abs(e.tod - tod) > 1e-3):
            break
        out += [r for r in e.of("TPV") if "time" in r and "lat" in r and r["mode"] >= 2
                and tod is not None and abs(_tod_iso(r["time"]) - tod) <= 1e-3]
    return out


def _latlon_fields(e: Entry) -> tuple[str, str]:
    f = e.fields
    k = 1 if e.stype in ("GGA", "GNS") else (2 if e.stype == "RMC" else 0)
    return f[k], f[k + 2]


def compare_fix(name: str, entries: list[Entry], ok: dict[int, dict[str, Any]],
                refused: dict[int, str]) -> Counter[str]:
    """Check the restated driver (``gpsd_fix``/``gpsd_status``) on every TPV a
    sentence determined, then every position sentence against it and against
    the position GPSD reported for its epoch."""
    n: Counter[str] = Counter()
    for i, tpv in attributed_tpvs(entries):
        s = entries[i]
        assert gpsd_fix(s) == (tpv["mode"] >= 2), (name, s.line, tpv)
        n["tpv_mode"] += 1
        epoch = epoch_before(entries, i)
        if epoch is not None and tpv["mode"] >= 2:
            top = max((x for x in map(gpsd_status, epoch) if x is not None), default=0)
            assert max(top, 1) == tpv.get("status", 1), (name, s.line, tpv)  # 0/1 not printed
            n["tpv_status"] += 1
    for i, e in enumerate(entries):
        if e.stype not in POSITION_TYPES:
            continue
        want = gpsd_class(e)
        ours = ok.get(e.n)
        if ours is None:
            # refusing a sentence GPSD takes no fix from loses nothing
            assert want == "none" or (name, e.line) in DISAGREEMENTS, (
                name, e.line, refused.get(e.n))
            n["refused"] += 1
            continue
        assert ours["kind"] == e.stype and ours["fix"] == want, (name, e.line, ours["fix"], want)
        n["fix" if want != "none" else "no_fix"] += 1
        if "lat" in ours and e.tod is not None:
            lat_f, lon_f = _latlon_fields(e)
            for r in epoch_tpvs(entries, i):
                # GPSD's position is the last one of the epoch: compare to the
                # resolution of both sentences (same receiver, same epoch)
                assert abs(ours["lat"] - r["lat"]) <= 2 * _resolution_deg(lat_f) + 1e-9, e.line
                assert abs(ours["lon"] - r["lon"]) <= 2 * _resolution_deg(lon_f) + 1e-9, e.line
                n["position"] += 1
    return n


def next_heading(entries: list[Entry], i: int) -> float | None:
    """The heading of the first ATT GPSD printed after the HDT ``entries[i]``
    and before the next HDT/THS (GPSD reports attitude with the cycle)."""
    for k in range(i, len(entries)):
        if k > i and entries[k].stype in ("HDT", "THS"):
            return None
        for a in entries[k].of("ATT"):
            if "heading" in a:
                return float(a["heading"])
    return None


def compare_attitude(entries: list[Entry], ok: dict[int, dict[str, Any]],
                     refused: dict[int, str]) -> Counter[str]:
    n: Counter[str] = Counter()
    for i, e in enumerate(entries):
        if e.stype not in ("HDT", "THS", "HDM", "ROT", "XDR"):
            continue
        ours = ok.get(e.n)
        atts = e.of("ATT")
        if e.stype == "HDT":
            if ours is None:
                # only an empty heading is refused, and GPSD reports none for it
                assert refused[e.n] == "empty" and not any("heading" in a for a in atts), e
                n["heading_empty"] += 1
                continue
            ref = next_heading(entries, i)
            assert ours["true"] is True and ref is not None, e.line
            assert ours["heading_deg"] == pytest.approx(ref, abs=1e-3), e.line
            n["heading"] += 1
        elif e.stype == "THS":
            # GPSD reads THS and stores nothing; the receiver's HDT of the same
            # epoch, as GPSD decoded it, is the reference
            j = next(k for k in range(i + 1, len(entries))
                     if entries[k].stype in ("HDT", "THS"))
            ref = next_heading(entries, j)
            assert entries[j].stype == "HDT" and ours is not None and ref is not None, e.line
            assert ours["heading_deg"] == pytest.approx(ref, abs=1e-3), e.line
            n["ths_heading"] += 1
        elif e.stype == "HDM":
            assert ours is not None and ours["true"] is False, e.line
            assert ours["heading_deg"] == pytest.approx(atts[0]["mheading"], abs=1e-6)
            n["magnetic_heading"] += 1
        elif e.stype == "ROT":
            assert ours is not None, e.line
            assert ours["rot_dpm"] == pytest.approx(atts[0]["rot"], abs=1e-9)
            n["rot"] += 1
        else:
            assert ours is not None, e.line
            for k in ("pitch", "roll"):
                if f"{k}_deg" in ours:
                    assert ours[f"{k}_deg"] == pytest.approx(atts[0][k], abs=1e-9)
                    n[k] += 1
    return n


#: comparisons each capture must give, counted from GPSD's .chk (its
#: sentences with and without a fix, its TPVs tied to a sentence, its ATT
#: reports), so that no comparison passes vacuously
MINIMUM: dict[str, dict[str, int]] = {
    "GPSmap-76S.log": {"no_fix": 36, "tpv_mode": 14},  # simulator mode: S, quality 8
    "furuno_gl_ga.log": {"fix": 16, "no_fix": 32, "position": 140, "tpv_mode": 3},
    "garmin-10x.log": {"fix": 18, "no_fix": 10, "position": 36, "tpv_status": 16},
    "hemi.log": {"fix": 6, "no_fix": 209, "position": 19, "tpv_mode": 56, "heading": 4,
                 "heading_empty": 211},
    "humminbird-M37.log": {"fix": 33, "position": 38, "tpv_status": 38},
    "nmea-rtk.log": {"fix": 244, "position": 244, "tpv_status": 123},
    "polarx2.log": {"fix": 20, "position": 68, "tpv_status": 8},
    "pypilot.log": {"magnetic_heading": 7, "rot": 7, "pitch": 8, "roll": 7},
    "rst39.log": {"fix": 44, "position": 50, "tpv_mode": 47, "heading": 4},
    "saab-r4.log": {"fix": 24, "no_fix": 12, "position": 100, "tpv_mode": 38, "heading": 12,
                    "rot": 12},
    "skytraq-PX1172RH_DS.log": {"fix": 27, "position": 39, "tpv_status": 3, "heading": 9,
                                "ths_heading": 9},
    "ublox-zed-f9p-nmea.log": {"fix": 87, "position": 98, "tpv_status": 31},
}


def test_every_capture_is_listed() -> None:
    """Every capture has GPSD's output beside it, a floor here and a line in the README."""
    readme = (DATA / "README.md").read_text()
    assert (DATA / "COPYING").is_file() and "BSD-2-Clause" in (DATA / "COPYING").read_text()
    for name in CAPTURES:
        assert (DATA / f"{name}.chk").is_file(), name
        assert f"| {name} |" in readme, name
    assert sorted(MINIMUM) == CAPTURES


@pytest.mark.parametrize("name", CAPTURES)
def test_capture_agrees_with_gpsd(name: str) -> None:
    entries = load_chk(name)
    ok, refused = zarco_decode(name)
    n = compare_fix(name, entries, ok, refused) + compare_attitude(entries, ok, refused)
    for key, least in MINIMUM[name].items():
        assert n[key] >= least, (key, n)
    # every position sentence was compared (or refused where GPSD has no fix)
    assert n["fix"] + n["no_fix"] + n["refused"] == sum(
        e.stype in POSITION_TYPES for e in entries)
    # nothing a real receiver sent is refused as malformed or out of range
    bad = {k: v for k, v in Counter(refused.values()).items()
           if k not in ("unsupported", "empty", "invalid", "framing")}
    assert not bad, (bad, [e.line for e in entries if refused.get(e.n) in bad][:5])
