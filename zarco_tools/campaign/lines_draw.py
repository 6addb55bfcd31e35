"""The lines and hold campaigns' drawers: the base scenario (the paper's
rectangle, or station keeping) in a drawn current against a drawn plant.

Lines: the mission's speed (``speed_mps``), a current of ``current_mps`` from
any direction, the plant (hull, thrust, lag, misalignment, mismatch of the
simulated boat; the runtime keeps the nominal model), the compass.  Targets:
cross-track RMS ≤ ``xtrack_rms_m`` and p95 ≤ ``xtrack_p95_m`` (from 15 m into
each leg).

Hold: the same current, plant and compass, and the boat's heading; targets:
distance to the hold point p95 ≤ ``hold_p95_m`` and max ≤ ``hold_max_m``.
"""

from __future__ import annotations

import itertools
import json
import math
from typing import Any, ClassVar

from zarco_tools.campaign.draw import Draw, Judgement
from zarco_tools.campaign.physics import top_speed
from zarco_tools.campaign.spec import CampaignSpec, Family

HULL = ("m_kg", "iz_kgm2", "x_udot", "y_vdot", "n_rdot", "x_u", "x_uu", "y_v", "y_vv",
        "n_r", "n_rr")
PLANT_RANGES: dict[str, tuple[float, float]] = {
    "current_mps": (0.0, 1.5), "hull_scale": (0.5, 1.5), "thrust_scale": (0.5, 1.5),
    "lag_s": (0.01, 1.0), "misalignment_deg": (-10.0, 10.0), "mismatch": (-0.3, 0.3),
    "compass_noise_deg": (0.0, 5.0), "compass_bias_deg": (-10.0, 10.0),
}


def _plant(d: Draw) -> dict[str, Any]:
    """The current, the simulated plant and the compass, as overrides; the
    drawn factors go into ``d.factors``."""
    from drivers.sim.params import ThrusterParams, VesselParams

    vp, tp = VesselParams(), ThrusterParams()
    cur, cur_dir = d.u("current_mps"), round(float(d.rng.uniform(0.0, 360.0)), 1)
    hull = {p: d.u("hull_scale") for p in HULL}
    thrust, lag = d.u("thrust_scale"), d.u("lag_s")
    phi1, phi2 = d.u("misalignment_deg", 2), d.u("misalignment_deg", 2)
    mismatch = d.u("mismatch")
    u_max = top_speed(vp.x_u * hull["x_u"], vp.x_uu * hull["x_uu"],
                      2.0 * tp.fwd_max_n * thrust)
    d.factors.update({"current_mps": cur, "current_to_deg": cur_dir, "thrust_scale": thrust,
                      "damping_scale": hull["x_uu"], "mass_scale": hull["m_kg"], "lag_s": lag,
                      "misalignment_deg": round(0.5 * (abs(phi1) + abs(phi2)), 2),
                      "mismatch": mismatch, "top_speed_mps": round(u_max, 3)})
    return {
        "world.current.speed_mps": cur, "world.current.direction_deg": cur_dir,
        "world.thrusters.fwd_max_n": round(tp.fwd_max_n * thrust, 2),
        "world.thrusters.rev_max_n": round(tp.rev_max_n * thrust, 2),
        "world.thrusters.lag_s": lag,
        "world.thrusters.phi1_deg": phi1, "world.thrusters.phi2_deg": phi2,
        "world.thrusters.mismatch": mismatch,
        "world.compass.noise_deg": d.u("compass_noise_deg", 2),
        "world.compass.bias_deg": d.u("compass_bias_deg", 2),
        **{f"world.vessel.{p}": round(getattr(vp, p) * f, 3) for p, f in hull.items()},
    }


def _json_ok(report: dict[str, Any]) -> bool:
    try:
        json.dumps(report, allow_nan=False)
    except ValueError:
        return False
    return True


def _judge(checks: list[tuple[str, str, float | None, float]], report: dict[str, Any]
           ) -> Judgement:
    """Each check (name, label, figure, target): fails when the figure is
    missing or above its target."""
    fails: dict[str, list[str]] = {}
    ratios = []
    for name, label, v, target in checks:
        if v is None or not math.isfinite(v) or v > target:
            fails.setdefault(name, []).append(f"{label} {v if v is None else round(v, 3)} > "
                                              f"{target:g}")
        ratios.append(v / target if v is not None and math.isfinite(v) else 99.0)
    if not _json_ok(report):
        fails["json"] = ["NaN in the report"]
        ratios.append(99.0)
    return Judgement(fails, {}, round(max(min(r, 99.0) for r in ratios), 3))


class LinesDrawer:
    kind: ClassVar[str] = "lines"
    targets: ClassVar[tuple[str, ...]] = ("xtrack_rms_m", "xtrack_p95_m")
    checks: ClassVar[tuple[str, ...]] = ("rms", "p95", "json")
    ranges: ClassVar[dict[str, tuple[float, float]]] = {
        **PLANT_RANGES, "speed_mps": (0.05, 3.0), "margin": (1.0, 10.0)}
    choices: ClassVar[dict[str, tuple[str, ...]]] = {}
    settings: ClassVar[dict[str, tuple[Any, ...]]] = {}
    figures: ClassVar[tuple[str, ...]] = (
        "stop", "sim_seconds", "xtrack_rms_m", "xtrack_p95_m", "xtrack_max_m",
        "corner_overshoot_max_m", "corner_overshoot_outside_max_m", "saturation_fraction",
        "command_step_rms", "nav_position_rms_m", "nav_heading_rms_deg", "faults")

    def required_ranges(self, spec: CampaignSpec, fam: Family) -> list[str]:
        return [*PLANT_RANGES, "speed_mps", "margin"]

    def required_choices(self, spec: CampaignSpec, fam: Family) -> list[str]:
        return []

    def check(self, spec: CampaignSpec) -> None:
        from zarco_core.config import ConfigError

        m = spec.scenario.get("mission", {})
        if m.get("kind", "lines") != "lines" or len(m.get("waypoints", [])) < 2:
            raise ConfigError(spec.file, "campaign.scenario", "a lines campaign needs a "
                              "lines mission in its base scenario")

    def draw(self, d: Draw) -> None:
        v = d.u("speed_mps", 2)
        sets = _plant(d)
        wps = d.spec.scenario["mission"]["waypoints"]
        length = sum(math.dist(a, b) for a, b in itertools.pairwise(wps))
        # the mission ends when done; the limit only stops a boat that cannot finish
        sets["scenario.max_duration_s"] = round(60.0 + d.u("margin", 2) * length / v, 1)
        sets["mission.speed_mps"] = v
        sets["world.heading_deg"] = round(float(d.rng.uniform(0.0, 360.0)), 1)
        d.sets.update(sets)
        d.factors["speed_mps"] = v

    def judge(self, spec: CampaignSpec, factors: dict[str, Any], report: dict[str, Any]
              ) -> Judgement:
        tg = spec.targets
        return _judge([("rms", "cross-track RMS", report.get("xtrack_rms_m"),
                        tg["xtrack_rms_m"]),
                       ("p95", "cross-track p95", report.get("xtrack_p95_m"),
                        tg["xtrack_p95_m"])], report)


class HoldDrawer:
    kind: ClassVar[str] = "hold"
    targets: ClassVar[tuple[str, ...]] = ("hold_p95_m", "hold_max_m")
    checks: ClassVar[tuple[str, ...]] = ("p95", "max", "json")
    ranges: ClassVar[dict[str, tuple[float, float]]] = dict(PLANT_RANGES)
    choices: ClassVar[dict[str, tuple[str, ...]]] = {}
    settings: ClassVar[dict[str, tuple[Any, ...]]] = {}
    figures: ClassVar[tuple[str, ...]] = (
        "stop", "sim_seconds", "hold_distance_p50_m", "hold_distance_p95_m",
        "hold_distance_max_m", "hold_seconds", "hold_thrust_mean_pct", "hold_command_step_rms",
        "nav_position_rms_m", "nav_heading_rms_deg", "faults")

    def required_ranges(self, spec: CampaignSpec, fam: Family) -> list[str]:
        return list(PLANT_RANGES)

    def required_choices(self, spec: CampaignSpec, fam: Family) -> list[str]:
        return []

    def check(self, spec: CampaignSpec) -> None:
        from zarco_core.config import ConfigError

        if not any(c.get("name") == "mode" and (c.get("args") or {}).get("mode") == "hold"
                   for c in spec.scenario.get("commands", [])):
            raise ConfigError(spec.file, "campaign.scenario", "a hold campaign needs a "
                              "scenario whose [[commands]] put the boat in hold")

    def draw(self, d: Draw) -> None:
        sets = _plant(d)
        sets["world.heading_deg"] = round(float(d.rng.uniform(0.0, 360.0)), 1)
        d.sets.update(sets)

    def judge(self, spec: CampaignSpec, factors: dict[str, Any], report: dict[str, Any]
              ) -> Judgement:
        tg = spec.targets
        return _judge([("p95", "distance p95", report.get("hold_distance_p95_m"),
                        tg["hold_p95_m"]),
                       ("max", "distance max", report.get("hold_distance_max_m"),
                        tg["hold_max_m"])], report)
