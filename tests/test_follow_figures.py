"""The follow report's figures on hand-built distance series, whose figures are
worked out by hand in each test, and on a simulated run recorded to MCAP, whose
figures are recomputed here from the recording read back with mcap's own
reader."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from zarco_tools.campaign.tables import format_summary, summarise, time_above
from zarco_tools.follow_distance import (
    Manoeuvre,
    manoeuvre_rows,
    merge_manoeuvres,
    recovery_s,
    settled_figures,
    settled_windows,
    time_above_by_phase,
    whole_figures,
)
from zarco_tools.follow_report import above_line, acquisition_time, sound_speed_figures

ROOT = Path(__file__).resolve().parents[1]
DT = 0.1


def series(end_s: float, pieces: list[tuple[float, float, float]], base: float = 0.5
           ) -> tuple[np.ndarray, np.ndarray]:
    """Samples every 0.1 s on [0, end_s): ``base`` m, except ``value`` on each
    [a, b) of ``pieces`` (a, b, value)."""
    k = np.arange(round(end_s / DT))
    t = k * DT
    d = np.full(t.size, base)
    for a, b, v in pieces:
        # integer sample indices: no rounding at the piece's edges
        d[(k >= round(a / DT)) & (k < round(b / DT))] = v
    return t, d


# ------------------------------------------------------------ whole-time figures


def test_whole_time_figures_count_the_approach_and_the_turns_but_not_before_acquisition(
) -> None:
    # 10 m before acquisition at 20 s (left out); the approach 5 m for 20 s, a turn
    # 8 m for 15 s, 0.5 m otherwise, to 400 s: 3800 samples from acquisition, of
    # which 200 at 5 m and 150 at 8 m.  Sorted, indices 3450..3649 hold 5 m, so
    # the 95th percentile (index 0.95·3799 = 3609.05) is 5 m; the median 0.5 m;
    # the max 8 m (not the 10 m before acquisition)
    t, d = series(400.0, [(0.0, 20.0, 10.0), (20.0, 40.0, 5.0), (200.0, 215.0, 8.0)])
    f = whole_figures(t, d, 20.0)
    assert f == {"distance_median_m": 0.5, "distance_p95_m": 5.0, "distance_max_m": 8.0}


def test_a_run_that_is_3_m_off_a_third_of_the_time_has_a_whole_time_median_that_says_so(
) -> None:
    # the case the settled figures hid: 4 m for 130 s of every 300 s after each
    # of three manoeuvres (43 %): the whole-time median is 0.5 m only if fewer
    # than half the samples are off — here 3900 of 9000 are, so the median is
    # still 0.5 m, but the p95 is 4 m; with 4 m for 160 s of every 300 s the
    # median is 4 m
    pieces = [(s, s + 130.0, 4.0) for s in (0.0, 300.0, 600.0)]
    t, d = series(900.0, pieces)
    f = whole_figures(t, d, 0.0)
    assert f["distance_median_m"] == 0.5 and f["distance_p95_m"] == 4.0
    t, d = series(900.0, [(s, s + 160.0, 4.0) for s in (0.0, 300.0, 600.0)])
    assert whole_figures(t, d, 0.0)["distance_median_m"] == 4.0


def test_never_acquired_gives_no_distance_figures() -> None:
    t, d = series(100.0, [])
    f = whole_figures(t, d, None)
    assert all(math.isnan(v) for v in f.values())
    assert acquisition_time([(0.0, "follow:wait"), (3.0, "follow:hold")]) is None
    assert acquisition_time([(0.0, "follow:wait"), (12.5, "follow:follow"),
                             (40.0, "follow:hold"), (45.0, "follow:follow")]) == 12.5


# ----------------------------------------------------------------- settled figures


def test_settled_figures_leave_out_the_minute_after_each_manoeuvre_and_the_hover() -> None:
    # the AUV starts moving at 30 s and turns at 200 s (an instant): the settled
    # windows are [90, 200) and [260, 400)
    man = [Manoeuvre(200.0, 200.0, math.pi / 2)]
    wins = settled_windows(30.0, man, 400.0)
    assert wins == [(90.0, 200.0), (260.0, 400.0)]
    # 8 m in the turn (left out); 2 m for 20 s at 300–320 s, inside a window:
    # 2500 settled samples of which 200 at 2 m; index 0.95·2499 = 2374.05 lies
    # among the 2 m (2300..2499): p95 2 m, median 0.5 m
    t, d = series(400.0, [(200.0, 215.0, 8.0), (300.0, 320.0, 2.0)])
    moving = t >= 30.0
    f = settled_figures(t, d, moving, 20.0, wins)
    assert f == {"settled_distance_median_m": 0.5, "settled_distance_p95_m": 2.0}
    # the AUV hovering (not moving) from 100 to 200 s: those samples are left out
    # too; with the 2 m stretch lengthened to 300–340 s it is 400 of 1500
    # settled samples, so the median stays 0.5 m and the p95 is 2 m
    t, d = series(400.0, [(200.0, 215.0, 8.0), (300.0, 340.0, 2.0)])
    f = settled_figures(t, d, (t >= 30.0) & ~((t >= 100.0) & (t < 200.0)), 20.0, wins)
    assert f == {"settled_distance_median_m": 0.5, "settled_distance_p95_m": 2.0}
    # ... while over the whole time the 8 m turn and the 2 m stretch both count
    assert whole_figures(t, d, 20.0)["distance_max_m"] == 8.0


def test_the_time_further_than_4_m_is_told_by_phase_against_the_p95_budget() -> None:
    """Acquired at 10 s, the AUV starts at 50 s, turns 90° at 200–210 s and
    180° at 300–320 s, runs to 500 s.  Further than 4 m: 10–20 s (6 m: the
    approach), 30–35 s (the hover), 70–80 s (the set-off: within the minute
    after the start), 205–215 s (the turn), 330–350 s (the U-turn's minute),
    400–402 s (straight) and 2–8 s (before acquisition: not counted)."""
    man = [Manoeuvre(200.0, 210.0, math.pi / 2), Manoeuvre(300.0, 320.0, math.pi)]
    t, d = series(500.0, [(2.0, 8.0, 9.0), (10.0, 20.0, 6.0), (30.0, 35.0, 4.5),
                          (70.0, 80.0, 5.0), (205.0, 215.0, 7.0), (330.0, 350.0, 12.0),
                          (400.0, 402.0, 4.2)])
    a = time_above_by_phase(t, d, 10.0, 50.0, man)
    assert a == pytest.approx({"hover": 15.0, "set_off": 10.0, "turn": 10.0, "uturn": 20.0,
                               "arc": 0.0, "straight": 2.0, "total": 57.0,
                               "budget": 0.05 * 490.0})
    # exactly 4 m is within the target; never acquired: nothing to tell
    t, d = series(100.0, [(10.0, 20.0, 4.0)])
    assert time_above_by_phase(t, d, 0.0, 50.0, [])["total"] == 0.0
    assert time_above_by_phase(t, d, None, 50.0, []) == {}
    # the summary's line names the phases that count and the budget
    line = above_line(a)
    assert "57.0 s" in line and "24.5 s" in line and "u-turn" not in line
    assert "uturn 20.0" in line and "set-off 10.0" in line and "arc" not in line
    # a campaign adds the missions up, counting those over their budget
    recs = [{"index": i, "family": "lawnmower", "factors": {}, "fails": {}, "exempt": {},
             "severity": 0.0, "scenario_seed": 1, "overrides": [],
             "figures": {"time_above_4m_s": {**a, "total": tot, "budget": 24.5}}}
            for i, tot in enumerate((57.0, 20.0))]
    tab = time_above(recs)
    assert tab["hover"] == 30.0 and tab["total"] == 77.0 and tab["budget"] == 49.0
    assert tab["missions"] == 2 and tab["over_budget"] == 1
    text = format_summary(summarise(recs, ("p95",), "follow.toml", []))
    assert "further than 4 m from the AUV: 77 s over 2 missions (1 over" in text
    assert "hover 30 s (39 %)" in text


def test_a_follow_campaign_draws_where_its_p95_goes(tmp_path: Path) -> None:
    """``above.png``: one stacked bar per family and one for all, a real PNG."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.image import imread

    from zarco_tools.campaign.plots import plot_time_above

    above = {"hover": 15.0, "set_off": 10.0, "turn": 0.0, "uturn": 20.0, "arc": 0.0,
             "straight": 2.0, "total": 47.0, "budget": 24.5}
    recs = [{"family": f, "figures": {"time_above_4m_s": above}}
            for f in ("lawnmower", "spiral")]
    p = plot_time_above(tmp_path, recs, "follow seed 1")
    assert p == str(tmp_path / "above.png")
    img = imread(p)
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 500
    assert plot_time_above(tmp_path, [{"family": "lines", "figures": {}}], "lines") is None


def test_a_manoeuvre_that_lasts_keeps_its_whole_length_out_of_the_settled_windows() -> None:
    arc = Manoeuvre(100.0, 290.0, math.tau, arc=True)
    assert settled_windows(20.0, [arc], 500.0) == [(80.0, 100.0), (350.0, 500.0)]
    # nothing settled left between two manoeuvres 50 s apart
    assert settled_windows(0.0, [Manoeuvre(100.0, 100.0, 1.0),
                                 Manoeuvre(150.0, 150.0, 1.0)], 170.0) == [(60.0, 100.0)]


# ------------------------------------------------------------------------- turns


def test_recovery_is_the_last_excursion_beyond_3_m_then_10_s_within() -> None:
    # turn at 200 s; 8 m until 215 s: the last sample beyond 3 m is at 214.9 s,
    # and the 10 s after it are within 3 m: recovered 14.9 s after the turn
    t, d = series(400.0, [(200.0, 215.0, 8.0)])
    assert recovery_s(t, d, 200.0, 200.0, 400.0) == pytest.approx(14.9)
    # never beyond 3 m: 0
    t, d = series(400.0, [(200.0, 215.0, 2.9)])
    assert recovery_s(t, d, 200.0, 200.0, 400.0) == 0.0
    # back within 3 m for only 8 s at a time until 300 s (beyond the minute after
    # the turn): never recovered
    pieces = [(s, s + 2.0, 4.0) for s in np.arange(200.0, 300.0, 10.0)]
    t, d = series(400.0, pieces)
    assert math.isnan(recovery_s(t, d, 200.0, 200.0, 400.0))
    # the run ends 5 s after the last excursion: not (yet) recovered
    t, d = series(220.0, [(200.0, 215.0, 8.0)])
    assert math.isnan(recovery_s(t, d, 200.0, 200.0, 220.0))


def test_the_minute_after_a_manoeuvre_ends_counts_for_its_recovery() -> None:
    # an arc 100–290 s; beyond 3 m at 330–335 s (within the minute after its
    # end) → recovered at 334.9 s, 234.9 s after its start; an excursion at
    # 360–365 s (beyond the minute) is not the arc's
    t, d = series(500.0, [(330.0, 335.0, 3.5), (360.0, 365.0, 3.5)])
    assert recovery_s(t, d, 100.0, 290.0, 500.0) == pytest.approx(234.9)


def test_manoeuvres_merge_a_lawnmower_end_and_keep_an_arc_whole() -> None:
    # two 90° switches 20 s apart: one U-turn of 180°; a 360° arc 100 s later
    # stays one arc; a switch 10 s after the arc's end is a turn of its own
    rad = math.radians
    items = [Manoeuvre(100.0, 100.0, rad(90.0)), Manoeuvre(120.0, 120.0, rad(90.0)),
             Manoeuvre(220.0, 410.0, rad(-360.0), arc=True),
             Manoeuvre(420.0, 420.0, rad(45.0)), Manoeuvre(900.0, 900.0, rad(30.0))]
    man = merge_manoeuvres(items, 800.0)
    assert [(m.start_s, m.end_s, round(math.degrees(m.angle_rad)), m.kind) for m in man] == [
        (100.0, 120.0, 180, "uturn"), (220.0, 410.0, -360, "arc"), (420.0, 420.0, 45, "turn")]
    assert Manoeuvre(0.0, 0.0, rad(90.0)).kind == "turn"
    assert Manoeuvre(0.0, 0.0, rad(-90.04)).kind == "turn"  # reported as −90.0°
    assert Manoeuvre(0.0, 0.0, rad(90.06)).kind == "uturn"  # reported as 90.1°
    assert Manoeuvre(0.0, 0.0, rad(-135.0)).kind == "uturn"


def test_turn_rows_peak_from_the_start_to_the_next_manoeuvre() -> None:
    man = [Manoeuvre(100.0, 120.0, math.pi), Manoeuvre(300.0, 300.0, -math.pi / 2)]
    # 9 m at 125–130 s (the U-turn's), 12 m at 310–320 (the second turn's)
    t, d = series(500.0, [(125.0, 130.0, 9.0), (310.0, 320.0, 12.0)])
    rows = manoeuvre_rows(t, d, man, 500.0)
    assert [(r["kind"], r["distance_max_m"], r["window_s"]) for r in rows] == [
        ("uturn", 9.0, 200.0), ("turn", 12.0, 200.0)]
    assert rows[0]["recovery_s"] == pytest.approx(29.9)
    assert rows[1]["recovery_s"] == pytest.approx(19.9)


# -------------------------------------------------------------------- sound speed


def test_sound_speed_estimate_and_its_error_from_300_s_after_acquisition() -> None:
    # tracks without an estimate: the configured value is the tracker's estimate
    plain = [SimpleNamespace(t=float(k)) for k in range(0, 600, 10)]
    f = sound_speed_figures(plain, 1500.0, 1480.0, 50.0)  # type: ignore[arg-type]
    assert f["sound_speed_est_mps"] == 1500.0 and f["sound_speed_true_mps"] == 1480.0
    assert f["sound_speed_error_max_pct"] == pytest.approx(20.0 / 1480.0 * 100.0)
    # an estimate converging from 1500 to 1481 by 340 s (acquired at 40 s): from
    # 340 s on the largest error is |1481 − 1480| / 1480
    est = [SimpleNamespace(t=float(k), sound_speed_mps=max(1481.0, 1500.0 - 0.1 * k))
           for k in range(0, 600, 10)]
    f = sound_speed_figures(est, 1500.0, 1480.0, 40.0)  # type: ignore[arg-type]
    assert f["sound_speed_est_mps"] == 1481.0
    assert f["sound_speed_error_max_pct"] == pytest.approx(1.0 / 1480.0 * 100.0)
    # the run ends before 300 s after acquisition: no figure
    assert math.isnan(sound_speed_figures(est[:30], 1500.0, 1480.0, 40.0)[  # type: ignore[arg-type]
        "sound_speed_error_max_pct"])


# ------------------------------------------------ a simulated arc, recomputed from MCAP


def _read_mcap(path: Path) -> dict[str, list[dict[str, Any]]]:
    from mcap.reader import make_reader

    out: dict[str, list[dict[str, Any]]] = {"/SimTruth": [], "/GuidanceStatus": [],
                                            "/AuvTrack": []}
    with path.open("rb") as fh:
        for _schema, channel, message in make_reader(fh).iter_messages(
                topics=list(out)):
            out[channel.topic].append(json.loads(message.data))
    return out


@pytest.fixture(scope="module")
def arc_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path]:
    from zarco_tools.scenario import load_scenario
    from zarco_tools.simulation import run_scenario

    # the AUV goes north 60 m, flies a full circle of 25 m radius to port, and
    # goes on north: one continuous turn of −360°
    path = tmp_path_factory.mktemp("arc") / "arc.mcap"
    scn = load_scenario(ROOT / "config" / "scenarios" / "follow_turn.toml", [
        "auv.waypoints=[[100.0, 100.0], [160.0, 100.0], [400.0, 100.0]]",
        "auv.arcs=[[1, 25.0, -360.0, 0.0]]", "auv.start_delay_s=30.0",
        "scenario.max_duration_s=330.0"], seed=3)
    return run_scenario(scn, record=str(path)).report, path


def test_a_circle_is_one_arc_judged_on_its_distance(arc_run: tuple[dict[str, Any], Path]
                                                    ) -> None:
    report, _ = arc_run
    (arc,) = report["turns"]
    assert arc["kind"] == "arc" and arc["angle_deg"] == pytest.approx(-360.0, abs=0.5)
    # 2π·25 m at 1 m/s, from the end of the 60 m leg (30 s hover + 60 s)
    assert arc["end_s"] - arc["t_s"] == pytest.approx(2 * math.pi * 25.0, abs=0.5)
    assert arc["t_s"] == pytest.approx(90.0, abs=1.0)
    json.dumps(report, allow_nan=False)


def test_the_whole_time_figures_match_the_recording(arc_run: tuple[dict[str, Any], Path]
                                                    ) -> None:
    report, path = arc_run
    rec = _read_mcap(path)
    acquired = next(g["t"] for g in rec["/GuidanceStatus"] if g["mode"] == "follow:follow")
    assert report["acquired_s"] == pytest.approx(acquired, abs=1e-6)
    truth = rec["/SimTruth"]
    d = np.array([math.hypot(s["x_m"] - s["auv_x_m"], s["y_m"] - s["auv_y_m"])
                  for s in truth if s["t"] >= acquired])
    assert d.size > 2500
    assert report["distance_median_m"] == pytest.approx(float(np.median(d)), abs=1e-9)
    assert report["distance_p95_m"] == pytest.approx(float(np.percentile(d, 95)), abs=1e-9)
    assert report["distance_max_m"] == pytest.approx(float(d.max()), abs=1e-9)
    # the arc's peak: the largest distance from its start to the end of the run
    (arc,) = report["turns"]
    da = [math.hypot(s["x_m"] - s["auv_x_m"], s["y_m"] - s["auv_y_m"])
          for s in truth if s["t"] >= arc["t_s"] - 0.05]
    assert arc["distance_max_m"] == pytest.approx(max(da), abs=1e-9)
    # the AUV's course in the recording turns through −360° during the arc
    psi = np.unwrap([s["auv_psi_rad"] for s in truth
                     if arc["t_s"] - 1.0 <= s["t"] <= arc["end_s"] + 1.0])
    assert math.degrees(psi[-1] - psi[0]) == pytest.approx(-360.0, abs=1.0)
    # the sound speed: the tracker's last estimate as recorded (the configured
    # value when its tracks carry none), against the simulated truth
    last = rec["/AuvTrack"][-1].get("sound_speed_mps")
    est = last if isinstance(last, float) and math.isfinite(last) else 1500.0
    assert report["sound_speed_est_mps"] == pytest.approx(est, abs=1e-9)
    assert report["sound_speed_true_mps"] == 1500.0
    assert abs(report["sound_speed_est_mps"] / 1500.0 - 1.0) <= 0.002
