"""CI-sized fuzz of the NMEA driver paths (the full run: ``tests/bench/fuzz.py``)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pynmea2

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
    # not vacuous: every path accepted some mutated sentences (checksum recomputed on
    # damaged content reaches the field parsers), and refused many more
    for path in fuzz.PATHS:
        assert r["accepted"].get(path, 0) > 20, r["accepted"]
        assert r["rejections"].get(f"{path}:checksum", 0) > 500
    assert r["rejections"]["gps:field"] > 50 and r["rejections"]["compass:field"] > 50
    assert r["frames_with_valid_checksum"] > 1000


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
