"""The follow campaign's drawer: random follow-the-AUV missions on the base
scenario (``config/scenarios/follow_turn.toml``).

Each mission draws, from the spec's ranges and weights:

* the LBL network: 2–N beacons (``beacons``) in a regular, random or elongated
  layout (``layout``) ``beacon_spread_m`` across, ``beacon_depth_m`` deep, the
  buoy listening at any of them; the AUV's route inside the network (beside
  the baseline, on one side, with two beacons);
* the AUV's route, by the family's ``route``: ``lawnmower`` (``legs`` legs of
  ``leg_m``, or ``leg_s`` at its speed, ``spacing_m`` apart: a U-turn each
  end), ``random`` (``legs`` legs of ``leg_s``, turns of ``turn_deg`` either
  way, full reversals with probability ``reversal_p``), ``arcs`` (``legs``
  legs with a continuous turn of ``arc_deg`` at radius ``arc_radius_m``
  between each two) or ``spiral`` (a leg in, a spiral of ``spiral_deg`` from
  ``spiral_radius_m`` growing ``spiral_growth_m`` per turn, a leg out);
  its speed ``auv_speed_mps``, depth, turn rate, the hover before it starts;
* the plan (``plan``): none, the AUV's route given to the runtime as
  ``[mission] auv_plan`` (``plan``), or that plan while the AUV leaves it
  part-way along a leg (``adaptive``: it turns off the plan and flies legs of
  its own);
* the calibration (``calibration``): exact; the true sound speed
  ``sound_speed_error_pct`` off the configured one; every beacon's true
  position up to ``survey_error_m`` from its surveyed one (what the runtime
  is configured with); every true turnaround ``turnaround_error_ms`` off the
  configured one; or all three;
* the detections (missed, false, jitter), the current, the plant (hull,
  thrust, lag, misalignment, mismatch of the simulated boat while the
  runtime keeps the nominal model), the compass, the boat's start and the
  tracker's prior.

The judgement (:mod:`zarco_tools.campaign.follow_judge`) and each mission's
closing speed (:mod:`zarco_tools.campaign.physics`) go with it.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from zarco_tools.campaign.draw import Draw, Judgement
from zarco_tools.campaign.follow_judge import CHECKS, TARGETS, judge_follow
from zarco_tools.campaign.physics import (
    least_closing_speed,
    straight_thrust,
    survey_scale_pct,
    top_speed,
)
from zarco_tools.campaign.routes import Route, bbox_centre, carry_on, one_side
from zarco_tools.campaign.spec import CampaignSpec, Family

#: hull parameters scaled in the simulated plant
HULL = ("m_kg", "iz_kgm2", "x_udot", "y_vdot", "n_rdot", "x_u", "x_uu", "y_v", "y_vv",
        "n_r", "n_rr")
#: the draws a family's route needs, by route
ROUTE_RANGES = {
    "lawnmower": ("legs", "spacing_m"),
    "random": ("legs", "leg_s", "turn_deg", "reversal_p"),
    "arcs": ("legs", "leg_s", "arc_radius_m", "arc_deg"),
    "spiral": ("leg_s", "spiral_radius_m", "spiral_growth_m", "spiral_deg"),
}
#: draws every family needs
COMMON_RANGES = (
    "beacon_spread_m", "beacon_depth_m", "auv_speed_mps", "auv_depth_m", "turn_rate_dps",
    "start_delay_s", "tail_s", "p_miss", "p_false", "jitter_s", "current_mps",
    "sound_speed_mps", "sound_speed_error_pct", "survey_error_m", "turnaround_s",
    "turnaround_error_ms", "auv_delay_s", "hull_scale", "thrust_scale", "lag_s",
    "misalignment_deg", "mismatch", "start_distance_m", "prior_error_m",
    "compass_noise_deg", "compass_bias_deg", "adaptive_at", "adaptive_turn_deg")
#: a mission lasts at least this long (s): the sound-speed target is judged from
#: 300 s after acquisition
MIN_DURATION_S = 420.0


def plan_supported() -> bool:
    """Whether this runtime takes the AUV's a-priori plan (``[mission] auv_plan``)."""
    from zarco_runtime.guidance.mission import MissionConfig

    return "auv_plan" in MissionConfig.__dataclass_fields__


class FollowDrawer:
    kind: ClassVar[str] = "follow"
    targets: ClassVar[tuple[str, ...]] = TARGETS
    checks: ClassVar[tuple[str, ...]] = CHECKS
    ranges: ClassVar[dict[str, tuple[float, float]]] = {
        "beacon_spread_m": (50.0, 5000.0), "beacon_depth_m": (0.0, 6000.0),
        "auv_speed_mps": (0.1, 3.0), "auv_depth_m": (0.0, 1000.0),
        "turn_rate_dps": (1.0, 45.0), "legs": (1.0, 50.0), "leg_s": (5.0, 3600.0),
        "leg_m": (5.0, 5000.0), "spacing_m": (1.0, 1000.0), "turn_deg": (1.0, 180.0),
        "reversal_p": (0.0, 1.0), "arc_radius_m": (5.0, 1000.0), "arc_deg": (10.0, 3600.0),
        "spiral_radius_m": (5.0, 1000.0), "spiral_growth_m": (0.0, 500.0),
        "spiral_deg": (90.0, 3600.0), "start_delay_s": (0.0, 600.0), "tail_s": (0.0, 3600.0),
        "p_miss": (0.0, 0.9), "p_false": (0.0, 0.9), "jitter_s": (0.0, 0.01),
        "current_mps": (0.0, 1.5), "sound_speed_mps": (1400.0, 1600.0),
        "sound_speed_error_pct": (-5.0, 5.0), "survey_error_m": (0.0, 50.0),
        "turnaround_s": (0.0, 1.0), "turnaround_error_ms": (-50.0, 50.0),
        "auv_delay_s": (0.0, 5.0), "hull_scale": (0.5, 1.5), "thrust_scale": (0.5, 1.5),
        "lag_s": (0.01, 1.0), "misalignment_deg": (-10.0, 10.0), "mismatch": (-0.3, 0.3),
        "start_distance_m": (0.0, 200.0), "prior_error_m": (0.0, 200.0),
        "compass_noise_deg": (0.0, 5.0), "compass_bias_deg": (-10.0, 10.0),
        "adaptive_at": (0.05, 0.95), "adaptive_turn_deg": (10.0, 180.0),
    }
    choices: ClassVar[dict[str, tuple[str, ...]]] = {
        "beacons": ("2", "3", "4", "5", "6"),
        "layout": ("regular", "random", "elongated"),
        "calibration": ("exact", "sound_speed", "survey", "turnaround", "all"),
        "plan": ("none", "plan", "adaptive"),
    }
    settings: ClassVar[dict[str, tuple[Any, ...]]] = {"route": tuple(ROUTE_RANGES)}
    figures: ClassVar[tuple[str, ...]] = (
        "stop", "sim_seconds", "acquired_s", "distance_median_m", "distance_p95_m",
        "distance_max_m", "settled_distance_median_m", "settled_distance_p95_m",
        "time_above_4m_s", "turns",
        "lost_max_s", "hold_max_s", "fix_gap_max_s", "track_lost_events",
        "sound_speed_est_mps", "sound_speed_true_mps", "sound_speed_configured_mps",
        "sound_speed_error_max_pct", "fix_interval_s", "fixes", "fix_error_rms_m",
        "track_error_rms_m", "course_error_rms_deg", "saturation_fraction",
        "nav_position_rms_m", "nav_heading_rms_deg", "faults", "tracker")

    def required_ranges(self, spec: CampaignSpec, fam: Family) -> list[str]:
        route = fam.settings.get("route", "lawnmower")
        need = [*COMMON_RANGES, *ROUTE_RANGES[route]]
        if route == "lawnmower" and not spec.has_range(fam, "leg_m"):
            need.append("leg_s")
        return need

    def required_choices(self, spec: CampaignSpec, fam: Family) -> list[str]:
        return list(self.choices)

    def check(self, spec: CampaignSpec) -> None:
        from zarco_core.config import ConfigError

        for fam in spec.families:
            w = spec.choice(fam, "plan")
            if (w.get("plan", 0.0) > 0.0 or w.get("adaptive", 0.0) > 0.0) \
                    and not plan_supported():
                raise ConfigError(spec.file, "choices.plan", "this runtime has no "
                                  "[mission] auv_plan: draw plan = { none = 1 } only")

    # ------------------------------------------------------------------ drawing

    def draw(self, d: Draw) -> None:
        from drivers.sim.params import ThrusterParams, VesselParams

        rng = d.rng
        nb = int(d.pick("beacons"))
        beacons, layout, spread = _beacons(d, nb)
        listener = int(rng.integers(0, nb))
        v = d.u("auv_speed_mps")
        turn_rate = d.u("turn_rate_dps", 1)
        route_kind = d.setting("route", "lawnmower")
        plan_kind = d.pick("plan")
        cx, cy = _centre(d, beacons, spread)
        for _attempt in range(200):
            planned, actual = _route(d, route_kind, plan_kind, v)
            pts = planned.points + actual.points
            mx, my = bbox_centre(pts)
            planned.shifted(cx - mx, cy - my)
            actual.shifted(cx - mx, cy - my)
            if nb > 2 or one_side(((beacons[0][0], beacons[0][1]),
                                   (beacons[1][0], beacons[1][1])),
                                  [*planned.points, *actual.points,
                                   carry_on(actual, 150.0)], 30.0):
                break
        wps = actual.rounded()
        start_delay = d.u("start_delay_s", 1)
        duration = round(max(start_delay + actual.length_m / v + d.u("tail_s"),
                             MIN_DURATION_S), 1)
        depth = d.u("auv_depth_m", 1)

        # calibration: the world (truth) against what the runtime is configured with
        calibration = d.pick("calibration")
        c_cfg = d.u("sound_speed_mps", 1)
        tau_cfg = [d.u("turnaround_s") for _ in range(nb)]
        delay = d.u("auv_delay_s")
        c_err = d.u("sound_speed_error_pct") if calibration in ("sound_speed", "all") else 0.0
        c_true = round(c_cfg * (1.0 + c_err / 100.0), 2)
        offsets = [(0.0, 0.0)] * nb
        if calibration in ("survey", "all"):
            offsets = []
            for _ in range(nb):
                r, a = d.u("survey_error_m"), rng.uniform(0.0, math.tau)
                offsets.append((r * math.cos(a), r * math.sin(a)))
        tau_true = list(tau_cfg)
        if calibration in ("turnaround", "all"):
            tau_true = [round(max(0.0, t + d.u("turnaround_error_ms", 2) / 1000.0), 5)
                        for t in tau_cfg]
        world_beacons = [[round(b[0] + o[0], 2), round(b[1] + o[1], 2), b[2]]
                         for b, o in zip(beacons, offsets, strict=True)]

        p_miss, p_false, jitter = d.u("p_miss"), d.u("p_false"), d.u("jitter_s", 5)
        cur, cur_dir = d.u("current_mps"), round(float(rng.uniform(0.0, 360.0)), 1)
        hull = {p: d.u("hull_scale") for p in HULL}
        thrust, lag = d.u("thrust_scale"), d.u("lag_s")
        phi1, phi2 = d.u("misalignment_deg", 2), d.u("misalignment_deg", 2)
        mismatch = d.u("mismatch")
        a0, r0 = rng.uniform(0.0, math.tau), d.u("start_distance_m", 1)
        asv = (round(wps[0][0] + r0 * math.cos(a0), 1), round(wps[0][1] + r0 * math.sin(a0), 1))
        heading = round(float(rng.uniform(0.0, 360.0)), 1)
        a1, r1 = rng.uniform(0.0, math.tau), d.u("prior_error_m", 1)
        prior = (round(wps[0][0] + r1 * math.cos(a1), 1),
                 round(wps[0][1] + r1 * math.sin(a1), 1))
        vp, tp = VesselParams(), ThrusterParams()
        d.sets.update({
            "scenario.max_duration_s": duration,
            "world.x_m": asv[0], "world.y_m": asv[1], "world.heading_deg": heading,
            "world.current.speed_mps": cur, "world.current.direction_deg": cur_dir,
            "world.thrusters.fwd_max_n": round(tp.fwd_max_n * thrust, 2),
            "world.thrusters.rev_max_n": round(tp.rev_max_n * thrust, 2),
            "world.thrusters.lag_s": lag,
            "world.thrusters.phi1_deg": phi1, "world.thrusters.phi2_deg": phi2,
            "world.thrusters.mismatch": mismatch,
            "world.compass.noise_deg": d.u("compass_noise_deg", 2),
            "world.compass.bias_deg": d.u("compass_bias_deg", 2),
            **{f"world.vessel.{p}": round(getattr(vp, p) * f, 3) for p, f in hull.items()},
            "auv.waypoints": wps, "auv.arcs": [[a[0], round(a[1], 1), round(a[2], 1),
                                                round(a[3], 1)] for a in actual.arcs],
            "auv.speed_mps": v, "auv.depth_m": depth,
            "auv.turn_rate_dps": turn_rate, "auv.start_delay_s": start_delay,
            "auv.at_end": "continue",
            "lbl.beacons": world_beacons, "lbl.turnaround_s": tau_true,
            "lbl.auv_delay_s": delay, "lbl.sound_speed_mps": c_true,
            "lbl.listener_beacon": listener, "lbl.jitter_s": jitter,
            "lbl.p_miss": p_miss, "lbl.p_false": p_false,
            "runtime.tracker.auv_depth_m": depth,
            "runtime.tracker.prior_north_m": prior[0], "runtime.tracker.prior_east_m": prior[1],
            "runtime.tracker.network.beacons": beacons,
            "runtime.tracker.network.turnaround_s": tau_cfg,
            "runtime.tracker.network.auv_delay_s": delay,
            "runtime.tracker.network.sound_speed_mps": c_cfg,
            "runtime.tracker.network.listener_beacon": listener,
        })
        if plan_kind != "none":
            d.sets["mission.auv_plan"] = [[round(x, 1), round(y, 1)] for x, y in
                                          _plan_points(planned)]
        # the closing speed of the true plant on every course of the route
        u_max = top_speed(vp.x_u * hull["x_u"], vp.x_uu * hull["x_uu"],
                          straight_thrust(tp.fwd_max_n * thrust, mismatch, phi1, phi2))
        closing = least_closing_speed(u_max, actual.courses, cur, math.radians(cur_dir), v)
        d.factors.update({
            "route": route_kind, "plan": plan_kind, "calibration": calibration,
            "beacons": nb, "layout": layout, "beacon_spread_m": round(spread, 1),
            "auv_speed_mps": v, "turn_rate_dps": turn_rate,
            "planned_turns_deg": [round(a) for a in actual.turns_deg],
            "sound_speed_error_pct": c_err,
            "survey_error_max_m": round(max(math.hypot(*o) for o in offsets), 3),
            "survey_scale_pct": round(survey_scale_pct(
                [(b[0], b[1]) for b in world_beacons], [(b[0], b[1]) for b in beacons]), 3),
            "turnaround_error_max_ms": round(max(abs(a - b) for a, b in
                                                 zip(tau_true, tau_cfg, strict=True))
                                             * 1000.0, 3),
            "p_miss": p_miss, "p_false": p_false, "jitter_ms": round(jitter * 1000.0, 3),
            "current_mps": cur, "thrust_scale": thrust, "damping_scale": hull["x_uu"],
            "lag_s": lag, "start_distance_m": r0, "prior_error_m": r1,
            "duration_s": duration, "top_speed_mps": round(u_max, 3),
            "closing_mps": round(closing, 3),
        })

    def judge(self, spec: CampaignSpec, factors: dict[str, Any], report: dict[str, Any]
              ) -> Judgement:
        return judge_follow(spec.targets, factors, report)


# ---------------------------------------------------------------- geometry


def _beacons(d: Draw, nb: int) -> tuple[list[list[float]], str, float]:
    """Beacon layout (north, east, depth), its kind, and its spread (m)."""
    rng = d.rng
    spread = d.u("beacon_spread_m", 1)
    if nb == 2:
        a = rng.uniform(0.0, math.tau)
        pts = [(0.0, 0.0), (spread * math.cos(a), spread * math.sin(a))]
        kind = "pair"
    else:
        kind = d.pick("layout")
        while True:
            if kind == "regular":
                a0 = rng.uniform(0.0, math.tau)
                pts = []
                for j in range(nb):
                    a = a0 + j * math.tau / nb + rng.uniform(-0.35, 0.35)
                    rad = 0.5 * spread * rng.uniform(0.8, 1.2)
                    pts.append((rad * math.cos(a), rad * math.sin(a)))
            else:
                w = spread * (0.45 if kind == "elongated" else 1.0)
                a = rng.uniform(0.0, math.tau)
                ca, sa = math.cos(a), math.sin(a)
                pts = []
                for _ in range(nb):
                    u, v = rng.uniform(-0.5, 0.5) * spread, rng.uniform(-0.5, 0.5) * w
                    pts.append((u * ca - v * sa, u * sa + v * ca))
            if min(math.dist(p, q) for i, p in enumerate(pts)
                   for q in pts[i + 1:]) >= 0.3 * spread:
                break
    beacons = [[round(x, 1), round(y, 1), d.u("beacon_depth_m", 1)] for x, y in pts]
    return beacons, kind, spread


def _centre(d: Draw, beacons: list[list[float]], spread: float) -> tuple[float, float]:
    """Centre of the AUV's mission: inside the network, or beside a single baseline."""
    rng = d.rng
    if len(beacons) == 2:
        (x0, y0, _), (x1, y1, _) = beacons
        bx, by = x1 - x0, y1 - y0
        n = math.hypot(bx, by)
        ux, uy = bx / n, by / n
        off = rng.uniform(90.0, 220.0) * rng.choice([-1.0, 1.0])
        along = rng.uniform(0.3, 0.7) * n
        return x0 + along * ux - off * uy, y0 + along * uy + off * ux
    cx = sum(b[0] for b in beacons) / len(beacons)
    cy = sum(b[1] for b in beacons) / len(beacons)
    return (cx + rng.uniform(-0.12, 0.12) * spread, cy + rng.uniform(-0.12, 0.12) * spread)


def _sign(d: Draw) -> float:
    return float(d.rng.choice([-1.0, 1.0]))


def _segments(d: Draw, kind: str, v: float) -> list[tuple[str, tuple[float, ...]]]:
    """The route's segments: ("line", (length m,)), ("turn", (deg,)), ("arc",
    (radius m, deg, growth m per 360°))."""
    segs: list[tuple[str, tuple[float, ...]]] = []
    if kind == "lawnmower":
        n = d.integer("legs")
        length = (d.u("leg_m", 1) if d.spec.has_range(d.fam, "leg_m")
                  else round(v * d.u("leg_s", 1), 1))
        spacing = d.u("spacing_m", 1)
        side = _sign(d)
        for k in range(n):
            segs.append(("line", (length,)))
            if k + 1 < n:
                turn = 90.0 * side * (1.0 if k % 2 == 0 else -1.0)
                segs += [("turn", (turn,)), ("line", (spacing,)), ("turn", (turn,))]
    elif kind == "random":
        n = d.integer("legs")
        for k in range(n):
            segs.append(("line", (round(v * d.u("leg_s", 1), 1),)))
            if k + 1 < n:
                a = 180.0 if d.rng.random() < d.u("reversal_p") else d.u("turn_deg", 1)
                segs.append(("turn", (a * _sign(d),)))
    elif kind == "arcs":
        n = max(2, d.integer("legs"))
        for k in range(n):
            segs.append(("line", (round(v * d.u("leg_s", 1), 1),)))
            if k + 1 < n:
                segs.append(("arc", (d.u("arc_radius_m", 1), d.u("arc_deg", 1) * _sign(d),
                                     0.0)))
    else:  # spiral
        segs.append(("line", (round(v * d.u("leg_s", 1), 1),)))
        segs.append(("arc", (d.u("spiral_radius_m", 1), d.u("spiral_deg", 1) * _sign(d),
                             d.u("spiral_growth_m", 1))))
        segs.append(("line", (round(v * d.u("leg_s", 1), 1),)))
    return segs


def _build(segs: list[tuple[str, tuple[float, ...]]], heading: float) -> Route:
    r = Route((0.0, 0.0), heading)
    for kind, args in segs:
        if kind == "line":
            r.line(args[0])
        elif kind == "turn":
            r.turn(args[0])
        else:
            r.arc(*args)
    return r


def _route(d: Draw, kind: str, plan_kind: str, v: float) -> tuple[Route, Route]:
    """(the plan, what the AUV flies): the same route, except for an adaptive
    mission, where the AUV leaves the plan part-way along one of its legs
    after the first and flies two legs of its own."""
    heading = float(d.rng.uniform(0.0, math.tau))
    segs = _segments(d, kind, v)
    planned = _build(segs, heading)
    if plan_kind != "adaptive":
        return planned, _build(segs, heading)
    lines = [i for i, (k, _a) in enumerate(segs) if k == "line"]
    j = lines[int(d.rng.integers(1, len(lines)))] if len(lines) > 1 else lines[0]
    frac = d.u("adaptive_at")
    own = [("line", (round(segs[j][1][0] * frac, 1),)),
           ("turn", (d.u("adaptive_turn_deg", 1) * _sign(d),)),
           ("line", (round(v * d.u("leg_s", 1), 1),)),
           ("turn", (d.u("adaptive_turn_deg", 1) * _sign(d),)),
           ("line", (round(v * d.u("leg_s", 1), 1),))]
    return planned, _build([*segs[:j], *own], heading)


def _plan_points(route: Route) -> list[tuple[float, float]]:
    """The plan as points: the waypoints, and every 15° of a continuous turn."""
    if not route.arcs:
        return [(w[0], w[1]) for w in route.waypoints]
    # the sampled points hold every waypoint and a point every ARC_STEP_DEG of
    # each turn: keep every third of a turn's
    out: list[tuple[float, float]] = []
    wp = {(round(w[0], 6), round(w[1], 6)) for w in route.waypoints}
    k = 0
    for p in route.points:
        key = (round(p[0], 6), round(p[1], 6))
        if key in wp:
            out.append(p)
            k = 0
        else:
            k += 1
            if k % 3 == 0:
                out.append(p)
    if out[-1] != route.points[-1]:
        out.append(route.points[-1])
    return out
