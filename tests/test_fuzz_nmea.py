"""CI-sized fuzz of the NMEA driver paths (the full run: ``tests/bench/fuzz.py``)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

import pynmea2

from drivers.nmea import NmeaError, split_checked
from zarco_core.messages import GpsVelocity, Heading

ROOT = Path(__file__).resolve().parents[1]


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("zarco_bench_fuzz",
                                                  ROOT / "tests" / "bench" / "fuzz.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


fuzz = _bench()


def test_no_exception_escapes_and_no_bad_checksum_is_used() -> None:
    r = fuzz.run(4000, seed=11)
    assert r["lines"] == 4000
    assert r["escaped_exceptions"] == 0, r["examples"]["escaped"]
    assert r["bad_checksum_used"] == 0, r["examples"]["bad_checksum_used"]
    assert r["implausible_used"] == 0, r["examples"]["implausible_used"]
    # not vacuous: every path accepted some mutated sentences (checksum recomputed on
    # damaged content reaches the field parsers), and refused many more
    for path in fuzz.PATHS:
        assert r["accepted"].get(path, 0) > 20, r["accepted"]
        assert r["rejections"].get(f"{path}:checksum", 0) > 500
    assert r["rejections"]["gps:field"] > 50 and r["rejections"]["compass:field"] > 50
    assert r["frames_with_valid_checksum"] > 1000


def test_out_of_range_values_are_never_accepted() -> None:
    """Checksum-valid, well-formed, physically impossible values on every field
    of every sentence type the drivers read: none is accepted."""
    r = fuzz.run_out_of_range()
    assert r["valid_refused"] == []  # the unmodified sentences all pass
    assert r["sentences"] >= 190
    assert r["accepted"] == 0, r["examples"]
    # the set covers every type and every driver path
    types = {line[1:6] if line[1] == "P" else line[3:6] for _p, line, _k, _v in
             fuzz.out_of_range_set()}
    assert types == {"GGA", "RMC", "GLL", "GNS", "VTG", "GST", "ZDA", "HDT", "THS", "HDG",
                     "HDM", "ROT", "XDR", "PZBAE", "PZBST", "PZTHS", "PZTHR"}


def test_same_seed_same_figures() -> None:
    a, b = fuzz.run(500, seed=3), fuzz.run(500, seed=3)
    a.pop("wall_s")
    b.pop("wall_s")
    assert a == b


def test_the_oracle_and_the_counters_catch_faulty_parsers() -> None:
    """A parser that skips the checksum, or lets a stray exception out, is caught."""
    assert fuzz.valid_checksum("$APHDM,218.634,M*39")
    assert fuzz.valid_checksum("$APXDR,A,0.135,D,PTCH*7c")  # lower-case hex is hex
    for bad in ("$APHDM,218.634,M*38", "$APHDM,218.634,M", "$APHDM,218.634,M*3",
                "$APHDM,218.634,M*390", "$APHDM,218.6é4,M*39", "$"):
        assert not fuzz.valid_checksum(bad), bad

    def lax(line: str) -> object:  # pynmea2's default: no checksum needed
        return pynmea2.parse(line, check=False)

    def buggy(line: str) -> object:
        return float(line.split(",")[1])

    r = fuzz.run(1500, seed=5, paths={"lax": lax, "buggy": buggy})
    assert r["bad_checksum_used"] > 0
    assert r["escaped_exceptions"] > 0


def test_the_plausibility_oracle_catches_a_wrapping_parser() -> None:
    """A parser that wraps headings and takes any speed is caught on both counts."""
    def wrapping(line: str) -> list[object]:
        address, fields = split_checked(line)
        if address[2:] == "HDT":
            deg = float(fields[0]) % 360.0
            return [Heading(0.0, "x", "HDT", math.radians(deg), True, float(fields[0]))]
        if address[2:] == "VTG":
            return [GpsVelocity(0.0, "x", "VTG", float(fields[4]) * 1852 / 3600, None)]
        raise NmeaError("unsupported", address)

    paths = dict(fuzz.PATHS, gps=wrapping)
    assert fuzz.run_out_of_range(paths)["accepted"] > 0
    assert fuzz.implausible(Heading(0.0, "x", "HDT", 1.0, True, 400.0)) is not None
    assert fuzz.implausible(GpsVelocity(0.0, "x", "VTG", 1e4, None)) is not None
    assert fuzz.implausible(GpsVelocity(0.0, "x", "VTG", 2.0, 6.0)) is None
