"""Property: no sequence of device faults makes the boat drive while driving is
unsafe.

Hypothesis draws a few faults of the simulated devices (unplugged, silent,
frozen, noisy, truncated, bad checksums, split writes, GPS fix changes; on the
GPS, the compass and the thruster controller, at any time and for any length)
and the failsafe table's actions for the three driving conditions (``idle``,
or ``continue``: then only the drive interlock stands between a fault and the
thrusters).  A lines mission autostarts; the run is simulated on the virtual
clock.  Judged from the bus alone, independently of the runtime's own code:

* while a driving condition holds (no compass heading for
  ``heading_lost_s`` or the heading estimate invalid; no thruster status for
  ``thruster_silent_s`` since the last one or since the first command; no GPS
  position fused for ``position_lost_s`` or the position estimate invalid),
  every thruster command is zero;
* once a failsafe whose action is ``idle`` has fired, nothing but zero is
  commanded again (no operator arms it again here);
* every command is finite and within −100..100.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.sim.faults import FaultSpec
from zarco_core.messages import Event, Heading, NavState, ThrusterCommand, ThrusterStatus
from zarco_runtime.runtime import Runtime
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"
RUN_S = 45.0
POSITION_LOST_S = 3.0  # shorter than the vessel's 10 s, so GPS faults reach it in a short run


@st.composite
def faults(draw: st.DrawFn) -> FaultSpec:
    device = draw(st.sampled_from(["gps", "compass", "thrusters"]))
    kinds = ["unplug", "silence", "freeze", "noise", "truncate", "bad_checksum", "split"]
    if device == "gps":
        kinds.append("fix")
    kind = draw(st.sampled_from(kinds))
    f = FaultSpec(kind=kind, device=device,
                  at_s=draw(st.floats(3.0, RUN_S - 5.0)),
                  duration_s=draw(st.floats(0.1, 12.0)),
                  fraction=draw(st.floats(0.2, 1.0)))
    if kind == "fix":
        f.fix = draw(st.sampled_from(["none", "single", "rtk_float"]))
    return f


class Judge:
    """The driving conditions, judged from the messages on the bus."""

    def __init__(self, rt: Runtime) -> None:
        self.fs = rt.cfg.failsafe
        self.heading_t: float | None = None
        self.status_t: float | None = None
        self.first_cmd_t: float | None = None
        self.nav: NavState | None = None
        self.unsafe: list[tuple[float, float, float, str]] = []
        self.bad: list[tuple[float, float, float]] = []
        self.cmds: list[tuple[float, float, float]] = []
        self.idle_fs_t: float | None = None
        rt.bus.listen(Heading, self.on_heading)
        rt.bus.listen(ThrusterStatus, self.on_status)
        rt.bus.listen(NavState, self.on_nav)
        rt.bus.listen(ThrusterCommand, self.on_cmd)
        rt.bus.listen(Event, self.on_event)

    def on_heading(self, m: Heading) -> None:
        self.heading_t = m.t

    def on_status(self, m: ThrusterStatus) -> None:
        self.status_t = m.t

    def on_nav(self, m: NavState) -> None:
        self.nav = m

    def on_event(self, e: Event) -> None:
        if e.kind == "failsafe" and "; action idle" in e.text and self.idle_fs_t is None \
                and e.text.split(":")[0] in ("heading_lost", "thruster_silent",
                                             "position_lost"):
            self.idle_fs_t = e.t

    def why_unsafe(self, t: float) -> str:
        fs, n = self.fs, self.nav
        if self.heading_t is None or t - self.heading_t > fs.heading_lost_s:
            return "heading"
        if n is None or not n.heading_valid:
            return "heading estimate"
        ref = self.status_t if self.status_t is not None else self.first_cmd_t
        if ref is not None and t - ref > fs.thruster_silent_s:
            return "thruster status"
        if n.gps_age_s + (t - n.t) > fs.position_lost_s or not n.pos_valid:
            return "position"
        return ""

    def on_cmd(self, c: ThrusterCommand) -> None:
        if self.first_cmd_t is None:
            self.first_cmd_t = c.t
        self.cmds.append((c.t, c.u1, c.u2))
        if not all(math.isfinite(u) and -100.0 <= u <= 100.0 for u in (c.u1, c.u2)):
            self.bad.append((c.t, c.u1, c.u2))
        moving = c.u1 != 0.0 or c.u2 != 0.0
        if not moving:
            return
        why = self.why_unsafe(c.t)
        if why:
            self.unsafe.append((c.t, c.u1, c.u2, why))
        if self.idle_fs_t is not None:
            self.unsafe.append((c.t, c.u1, c.u2, "after an idle failsafe"))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(faults(), min_size=1, max_size=4),
       st.sampled_from(["idle", "continue"]), st.sampled_from(["idle", "continue"]),
       st.sampled_from(["idle", "continue", "hold"]), st.integers(1, 1000))
def test_no_thrust_while_driving_is_unsafe(plan: list[FaultSpec], heading: str,
                                           position: str, thrusters: str, seed: int) -> None:
    scn = load_scenario(SCENARIOS / "rectangle.toml", [
        f"scenario.max_duration_s={RUN_S}",
        f"runtime.failsafe.position_lost_s={POSITION_LOST_S}",
        f'runtime.failsafe.heading_lost="{heading}"',
        f'runtime.failsafe.position_lost="{position}"',
        f'runtime.failsafe.thruster_silent="{thrusters}"'], seed)
    scn.faults = plan
    judged: dict[str, Any] = {}

    async def watch(rt: Runtime) -> None:
        judged["judge"] = Judge(rt)

    run_scenario(scn, extra_tasks=[watch])
    j: Judge = judged["judge"]
    assert j.cmds, "no command was sent at all"
    assert not j.bad, j.bad[:5]
    assert not j.unsafe, (j.unsafe[:5], [f.label for f in plan])


def test_the_property_sees_thrust_when_nothing_goes_wrong() -> None:
    """The judge is not vacuous: without faults the mission drives."""
    scn = load_scenario(SCENARIOS / "rectangle.toml", [f"scenario.max_duration_s={RUN_S}"], 1)
    judged: dict[str, Any] = {}

    async def watch(rt: Runtime) -> None:
        judged["judge"] = Judge(rt)

    run_scenario(scn, extra_tasks=[watch])
    j: Judge = judged["judge"]
    moving = [c for c in j.cmds if c[1] != 0.0 or c[2] != 0.0]
    assert len(moving) > 0.8 * len(j.cmds) and not j.unsafe


def test_with_continue_the_interlock_alone_holds_the_thrust_then_lets_go() -> None:
    """heading_lost = continue: the mode stays lines, the interlock gives zero while
    the compass is silent (past heading_lost_s), and the boat drives on after."""
    scn = load_scenario(SCENARIOS / "rectangle.toml", [
        f"scenario.max_duration_s={RUN_S}", 'runtime.failsafe.heading_lost="continue"'], 1)
    scn.faults = [FaultSpec(kind="silence", device="compass", at_s=20.0, duration_s=3.0)]
    judged: dict[str, Any] = {}

    async def watch(rt: Runtime) -> None:
        judged["judge"] = Judge(rt)

    run_scenario(scn, extra_tasks=[watch])
    j: Judge = judged["judge"]
    assert not j.unsafe
    lim = j.fs.heading_lost_s
    during = [c for c in j.cmds if 20.0 + lim + 0.06 < c[0] < 23.0]
    after = [c for c in j.cmds if 24.0 < c[0] < 30.0]
    assert during and all(c[1] == c[2] == 0.0 for c in during)
    assert after and sum(c[1] != 0.0 or c[2] != 0.0 for c in after) > 0.8 * len(after)
