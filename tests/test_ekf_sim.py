"""Navigation EKF against the simulator's truth (its figures at CI size).

Every run drives :class:`drivers.sim.world.SimWorld` through the real NMEA
framer and parsers (``zarco_tools.ekf_eval``); the boat follows the
paper's 100 m × 50 m rectangle at 1 m/s (or a shorter path) with a line-of-sight
pilot reading the truth, with the gusts of config/scenarios/rectangle.toml.
One seeded run is about 1.5 s.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import statistics
from typing import Any

import pytest

from zarco_core.messages import FixQuality, GpsFix, Heading
from zarco_tools.ekf_eval import (
    JUMP_AT_S,
    OUTAGE_START_S,
    Case,
    Result,
    circle_case,
    current_case,
    fixed_case,
    float_case,
    jump_case,
    jump_figures,
    outage_case,
    run,
)

#: χ² quantiles used below (scipy is not a dependency): χ²₅ 99 % and the two-sided
#: 99 % band of a χ² with 5·N degrees of freedom, by the Wilson–Hilferty approximation
CHI2_5_99 = 15.086


def chi2_band(dof: int, z: float = 2.576) -> tuple[float, float]:
    """Two-sided band (z = 2.576: 99 %) of a χ²(dof) variable, Wilson–Hilferty."""
    a = 2.0 / (9.0 * dof)
    return (dof * (1 - a - z * math.sqrt(a)) ** 3, dof * (1 - a + z * math.sqrt(a)) ** 3)


@pytest.fixture(scope="module")
def fixed() -> Result:
    return run(fixed_case(1))


@pytest.fixture(scope="module")
def nees_runs(fixed: Result) -> list[Result]:
    return [fixed] + [run(fixed_case(s)) for s in (2, 3, 4)]


# ----------------------------------------------------------------- position


def test_rtk_fixed_position_rms(fixed: Result) -> None:
    assert fixed.parse_errors == 0
    assert fixed.pos_rms() <= 0.02
    assert fixed.pos_rms() < 0.6 * fixed.gps_rms()  # better than the raw fixes
    assert all(s.pos_valid for s in fixed.window())


def test_rtk_float_position_rms() -> None:
    """σ 0.3 m white: ≤ 0.25 m.  The simulator adds the receiver's own slowly drifting
    float offset (0.2 m per axis, τ 60 s) on top, which no estimator can see: then
    the figure is per axis, and the filter still removes most of the raw error."""
    white = run(Case(fix="rtk_float", float_bias_m=0.0, duration_s=200.0))
    assert white.pos_rms() <= 0.25
    biased = run(float_case(1))
    assert biased.pos_rms() / math.sqrt(2.0) <= 0.25
    assert biased.pos_rms() < 0.75 * biased.gps_rms()


# ------------------------------------------------------------------ heading


def test_heading_rms_once_bias_and_current_are_separable(fixed: Result) -> None:
    """Compass noise 1°, bias 2°, no current, 1 m/s: ≤ 0.5° from the moment the boat
    has headed in opposite directions (third leg), and the bias is learned."""
    assert fixed.heading_rms_observable() <= 0.5
    bc = math.degrees(fixed.status.state["compass_bias_rad"])
    assert bc == pytest.approx(2.0, abs=0.6)
    # before that, the heading error stays within the compass's bias (no divergence)
    assert max(abs(s.epsi_deg) for s in fixed.window()) < 5.0


def test_heading_rms_with_a_calibration_circle() -> None:
    """A 30 s turn before the mission makes bias and current separable at once:
    ≤ 0.5° over the whole rectangle, with or without a 0.3 m/s current."""
    assert run(circle_case(1)).heading_rms() <= 0.5
    assert run(circle_case(1, current_mps=0.3)).heading_rms() <= 0.5


def test_heading_rms_without_current_state() -> None:
    """Where the water is known to be still, estimate_current = false resolves the
    bias on the first leg already."""
    r = run(Case(ekf={"estimate_current": False}))
    assert r.heading_rms() <= 0.5


def test_current_is_estimated_and_heading_recovers() -> None:
    """A 0.3 m/s current across the first leg: the crab (17°) is not taken for a
    compass bias; after the third leg the current and the bias are both right."""
    r = run(current_case(1))
    st = r.status.state
    assert math.hypot(st["current_n_mps"], st["current_e_mps"] - 0.3) < 0.05
    assert math.degrees(st["compass_bias_rad"]) == pytest.approx(2.0, abs=0.6)
    assert r.heading_rms_observable() <= 0.6
    assert max(abs(s.epsi_deg) for s in r.window()) < 6.0


def test_why_the_current_is_estimated_by_default() -> None:
    """The still-water filter in a 0.3 m/s cross current takes the 17° crab for a
    compass bias: its heading is degrees off where the default filter's is not."""
    still = run(Case(current_mps=0.3, ekf={"estimate_current": False}, duration_s=200.0))
    default = run(Case(current_mps=0.3, duration_s=200.0))
    assert still.heading_rms() > 3.0
    assert default.heading_rms() < 0.5 * still.heading_rms()


# -------------------------------------------------------------- consistency


def test_nees_within_chi2_bounds(nees_runs: list[Result]) -> None:
    """NEES of (x, y, vn, ve, ψ), four seeds, sampled every 10 s: the mean lies in the
    two-sided 99 % χ² band (counting one independent sample per 30 s, the errors
    being correlated over tens of seconds), and few samples exceed χ²₅ 99 %."""
    samples = [s.nees for r in nees_runs for s in r.window()[::100]]
    n_ind = max(1, len(samples) // 3)
    lo, hi = chi2_band(5 * n_ind)
    mean = statistics.fmean(samples)
    assert lo / n_ind <= mean <= hi / n_ind, (mean, lo / n_ind, hi / n_ind)
    assert sum(x > CHI2_5_99 for x in samples) <= 0.05 * len(samples)


# ------------------------------------------------------------------ outage


def test_gps_outage_dead_reckons_with_growing_covariance() -> None:
    """1 m/s on a straight leg, GPS lost for 30 s: ≤ 1 m after 10 s, ≤ 5 m after
    30 s; σ grows throughout; pos_valid drops after dr_max_s (10 s) and comes back
    with the GPS."""
    case = dataclasses.replace(outage_case(1), duration_s=OUTAGE_START_S + 40.0)
    r = run(case)
    t0 = OUTAGE_START_S
    assert r.error_at(t0 + 10.0) <= 1.0
    assert r.error_at(t0 + 30.0) <= 5.0
    during = [s for s in r.samples if t0 + 0.2 <= s.t <= t0 + 30.0]
    sig = [s.sigma[0] for s in during]
    assert all(b >= a for a, b in itertools.pairwise(sig))
    assert sig[-1] > 5 * sig[0]
    assert all(s.pos_valid for s in during if s.t <= t0 + 9.8)
    assert not any(s.pos_valid for s in during if s.t >= t0 + 10.2)
    back = [s for s in r.samples if s.t >= t0 + 33.0]
    assert all(s.pos_valid for s in back) and math.hypot(back[-1].ex, back[-1].ey) < 0.05
    # heading stays good on compass + gyro
    assert max(abs(s.epsi_deg) for s in during) < 2.0


# ----------------------------------------------------------- fix-type changes


def test_rtk_fixed_to_single_jump_is_absorbed() -> None:
    """RTK fixed → single on a straight leg (a metres-sized jump), the pilot steering
    on the estimate: no spike in heading, velocity or position, no thruster command
    changes by more than 20 in the following second."""
    r = run(jump_case(1))
    f = jump_figures(r)
    assert f["jump_max_du"] <= 20.0
    assert f["jump_heading_change_deg"] <= 0.5
    assert f["jump_vel_change_mps"] <= 0.15
    assert f["jump_pos_change_m"] <= 0.15
    raw = max(math.hypot(*s.gps_err) for s in r.samples if JUMP_AT_S <= s.t <= JUMP_AT_S + 1)
    assert raw > 1.0  # there was a jump to absorb
    assert r.status.counters["fix_changes"] == 1
    assert r.status.fix is FixQuality.SINGLE
    # the estimate stays near the truth (it was anchored by RTK) and says it is less sure
    assert math.hypot(r.samples[-1].ex, r.samples[-1].ey) < 0.5
    assert r.samples[-1].sigma[0] > 5 * r.samples[-10 * 25].sigma[0]


def test_single_to_rtk_fixed_glides_onto_the_better_solution() -> None:
    """The reverse: the published estimate moves to the RTK solution smoothly
    (upgrade_glide_s = 10 s), not in a step, says so in its covariance, and ends on it."""
    r = run(Case(fix="single", fix_schedule=((100.0, "rtk_fixed"),), duration_s=180.0,
                 waypoints=((0.0, 0.0), (200.0, 0.0))))
    before = [s for s in r.samples if 90.0 <= s.t < 100.0]
    assert statistics.fmean(math.hypot(s.ex, s.ey) for s in before) > 0.3  # single was off
    after = [s for s in r.samples if s.t >= 100.0]
    steps = [math.hypot(b.ex - a.ex, b.ey - a.ey) for a, b in itertools.pairwise(after)]
    assert max(steps) < 0.1  # per 0.1 s epoch
    assert all(math.hypot(s.ex, s.ey) < 3.0 * max(s.sigma[0], s.sigma[1]) + 0.03
               for s in after)
    assert math.hypot(after[-1].ex, after[-1].ey) < 0.05


# ------------------------------------------------------------ time of validity


def test_latency_configured_is_latency_removed() -> None:
    """GPS and compass sentences delivered late (0.2 s, 0.1 s): with the latencies
    configured, as good as on time; without, the position lags by speed × delay."""
    late = {"duration_s": 120.0, "gps_delay_s": 0.2, "compass_delay_s": 0.1}
    on_time = run(Case(duration_s=120.0))
    configured = run(Case(**late, ekf={"gps_latency_s": 0.2, "compass_latency_s": 0.1}))
    ignored = run(Case(**late))
    # samples are taken at the arrival clock: compare the estimate 0.2 s after validity
    assert configured.pos_rms() <= 0.02
    assert configured.pos_rms() <= 1.5 * on_time.pos_rms() + 0.005
    assert ignored.pos_rms() > 0.1
    assert configured.status.counters["replays"] > 1000


# ---------------------------------------------------------------- compass faults


def _freeze(t0: float, t1: float) -> Any:
    """Tamper: the compass repeats its reading from ``t0`` until ``t1``."""
    held: dict[str, Heading] = {}

    def tamper(m: Any, t: float) -> Any:
        if isinstance(m, Heading) and t0 <= t < t1:
            h = held.setdefault("h", m)
            return dataclasses.replace(h, t=m.t)
        return m

    return tamper


def test_frozen_compass_is_flagged_and_rejected() -> None:
    """The compass freezes just before the first corner while the boat turns 90°."""
    r = run(Case(duration_s=140.0, tamper=_freeze(95.0, 115.0)))
    c = r.status.counters
    assert c["compass_frozen"] == 1 and c["compass_rejected_fault"] > 100
    w = [s for s in r.samples if 95.0 <= s.t <= 140.0]
    assert max(abs(s.epsi_deg) for s in w) < 3.5  # gyro carried the heading
    assert not r.status.compass_frozen  # it cleared when the compass came back


def test_jumping_compass_is_flagged_and_rejected() -> None:
    """For 10 s every third compass reading is off by ±40°."""
    count = [0]

    def tamper(m: Any, t: float) -> Any:
        if isinstance(m, Heading) and 60.0 <= t < 70.0:
            count[0] += 1
            if count[0] % 3 == 0:
                off = math.radians(40.0 if count[0] % 2 else -40.0)
                return dataclasses.replace(m, heading_rad=(m.heading_rad + off) % math.tau,
                                           raw_deg=m.raw_deg + math.degrees(off))
        return m

    base = run(Case(duration_s=90.0))
    r = run(Case(duration_s=90.0, tamper=tamper))
    c = r.status.counters
    assert c["compass_jumping"] >= 1 and c["compass_rejected_fault"] > 50
    w = [s for s in r.samples if 60.0 <= s.t <= 90.0]
    wb = [s for s in base.samples if 60.0 <= s.t <= 90.0]
    assert max(abs(a.epsi_deg - b.epsi_deg) for a, b in zip(w, wb, strict=True)) < 0.5
    assert not r.status.compass_jumping


def test_gps_position_outlier_is_gated() -> None:
    def tamper(m: Any, t: float) -> Any:
        if isinstance(m, GpsFix) and m.sentence == "GGA" and abs(t - 50.0) < 1e-6:
            return dataclasses.replace(m, lat_deg=m.lat_deg + 4.0 / 111_000.0)
        return m

    r = run(Case(duration_s=60.0, tamper=tamper))
    assert r.status.counters["pos_rejected"] >= 1
    assert max(math.hypot(s.ex, s.ey) for s in r.samples if 49.0 <= s.t <= 52.0) < 0.05
