"""Property: no sequence of device faults makes the boat drive while driving is
unsafe, from a condition's onset until its failsafe clears.

Hypothesis draws a few faults of the simulated devices (unplugged, silent,
frozen, noisy, truncated, bad checksums, split writes, GPS fix changes; on the
GPS, the compass and the thruster controller, at any time and for any length),
often a device that flaps (silent, then answering for a moment, again and
again), the failsafe table's actions for the three driving conditions
(``idle``; ``continue``, where the mode goes on and only the latch stands
between a fault and the thrusters; ``hold`` and ``return`` for the thruster
controller, the table allowing them there only) and ``clear_after_s``
(0-4 s).  A lines mission autostarts; the run is simulated on the
virtual clock.  Judged from the bus alone, independently of the runtime's own
code:

* while a driving condition holds (no compass heading for
  ``heading_lost_s`` or the heading estimate invalid; no thruster status for
  ``thruster_silent_s`` since the last one or since the first command; no GPS
  position fused for ``position_lost_s`` or the position estimate invalid),
  every thruster command is zero;
* once the boat has driven, a condition seen at a command holds the thrust at
  zero until ``clear_after_s`` later (the condition latches, as a failsafe does);
* while a driving failsafe is active, from the event of its entry to the event
  of its clearing, every thruster command is zero, whatever its action;
* once a failsafe whose action is ``idle`` has fired, nothing but zero is
  commanded again (no operator arms it again here);
* every command is finite and within −100..100.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, example, given, settings
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


@st.composite
def flapping(draw: st.DrawFn) -> list[FaultSpec]:
    """One device silent again and again, answering between for a moment (shorter
    or longer than ``clear_after_s``)."""
    device = draw(st.sampled_from(["gps", "compass", "thrusters"]))
    t = draw(st.floats(3.0, 20.0))
    out = []
    for _ in range(draw(st.integers(2, 8))):
        d = draw(st.floats(0.1, 3.0))
        out.append(FaultSpec(kind="silence", device=device, at_s=t, duration_s=d))
        t += d + draw(st.floats(0.05, 2.5))
        if t > RUN_S - 5.0:
            break
    return out


#: a failsafe's entry and clearing, as the supervisor tells them
ENTRY = re.compile(r"^(position_lost|heading_lost|thruster_silent): ")
CLEARED = re.compile(r"^(position_lost|heading_lost|thruster_silent) cleared \(")


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
        #: the driving failsafes active (entered, not cleared) and every entry
        self.active: set[str] = set()
        self.entries: list[tuple[float, str]] = []
        self.clears: list[tuple[float, str]] = []
        #: the last command time at which a condition held, once the boat has driven
        self.driven = False
        self.last_unsafe_t = -math.inf
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
        if e.kind != "failsafe":
            return
        if (m := CLEARED.match(e.text)) is not None:
            assert m[1] in self.active, f"{m[1]} cleared but never entered: {e.text}"
            self.active.discard(m[1])
            self.clears.append((e.t, m[1]))
        elif (m := ENTRY.match(e.text)) is not None:
            self.active.add(m[1])
            self.entries.append((e.t, m[1]))
            if "; action idle" in e.text and self.idle_fs_t is None:
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
        why = self.why_unsafe(c.t)
        if why and self.driven:
            self.last_unsafe_t = c.t
        if not moving:
            return
        self.driven = True
        if why:
            self.unsafe.append((c.t, c.u1, c.u2, why))
        elif c.t - self.last_unsafe_t < self.fs.clear_after_s:
            self.unsafe.append((c.t, c.u1, c.u2, f"{c.t - self.last_unsafe_t:.2f} s after "
                                "a driving condition, within clear_after_s"))
        if self.active:
            self.unsafe.append((c.t, c.u1, c.u2, f"failsafe active: {sorted(self.active)}"))
        if self.idle_fs_t is not None:
            self.unsafe.append((c.t, c.u1, c.u2, "after an idle failsafe"))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(faults(), min_size=1, max_size=3), st.one_of(st.just([]), flapping()),
       st.sampled_from(["idle", "continue"]), st.sampled_from(["idle", "continue"]),
       st.sampled_from(["idle", "continue", "hold", "return"]), st.floats(0.0, 4.0),
       st.integers(1, 1000))
# a compass that flaps while the GPS is unplugged: the runtime closes its compass
# port to reopen it while the simulated compass still sends (it once crashed the rig)
@example([FaultSpec(kind="unplug", device="gps", at_s=4.087, duration_s=0.218, fraction=0.2)],
         [FaultSpec(kind="silence", device="compass", at_s=3.0, duration_s=3.0),
          FaultSpec(kind="silence", device="compass", at_s=7.357, duration_s=0.680)],
         "idle", "idle", "idle", 0.0, 1)
def test_no_thrust_while_driving_is_unsafe(plan: list[FaultSpec], flaps: list[FaultSpec],
                                           heading: str, position: str, thrusters: str,
                                           clear_after_s: float, seed: int) -> None:
    scn = load_scenario(SCENARIOS / "rectangle.toml", [
        f"scenario.max_duration_s={RUN_S}",
        f"runtime.failsafe.position_lost_s={POSITION_LOST_S}",
        f"runtime.failsafe.clear_after_s={clear_after_s}",
        f'runtime.failsafe.heading_lost="{heading}"',
        f'runtime.failsafe.position_lost="{position}"',
        f'runtime.failsafe.thruster_silent="{thrusters}"'], seed)
    plan = plan + flaps
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


def _watched(scn: Any) -> Judge:
    judged: dict[str, Any] = {}

    async def watch(rt: Runtime) -> None:
        judged["judge"] = Judge(rt)

    run_scenario(scn, extra_tasks=[watch])
    j: Judge = judged["judge"]
    return j


def test_with_continue_the_latch_holds_the_thrust_until_the_failsafe_clears() -> None:
    """heading_lost = continue: the mode stays lines; zero thrust from the compass's
    silence (past heading_lost_s) until the failsafe clears, clear_after_s after
    the compass is back; the boat drives on after."""
    scn = load_scenario(SCENARIOS / "rectangle.toml", [
        f"scenario.max_duration_s={RUN_S}", 'runtime.failsafe.heading_lost="continue"'], 1)
    scn.faults = [FaultSpec(kind="silence", device="compass", at_s=20.0, duration_s=3.0)]
    j = _watched(scn)
    assert not j.unsafe, j.unsafe[:5]
    lim, wait = j.fs.heading_lost_s, j.fs.clear_after_s
    assert [n for _, n in j.entries] == ["heading_lost"] == [n for _, n in j.clears]
    (t_in, _), (t_out, _) = j.entries[0], j.clears[0]
    assert 20.0 + lim <= t_in < 20.0 + lim + 0.2
    assert 23.0 + wait <= t_out < 23.0 + wait + 0.2
    during = [c for c in j.cmds if 20.0 + lim + 0.06 < c[0] < t_out]
    after = [c for c in j.cmds if t_out + 0.1 < c[0] < t_out + 5.0]
    assert during and all(c[1] == c[2] == 0.0 for c in during)
    assert after and sum(c[1] != 0.0 or c[2] != 0.0 for c in after) > 0.8 * len(after)


def test_a_flapping_thruster_controller_gives_no_thrust_between_its_flaps() -> None:
    """thruster_silent = continue and a thruster controller that answers now and then
    (silent 1 s, answering 0.5 s, six times): the failsafe enters at the first
    silence and clears only clear_after_s after the last; no thrust in between."""
    scn = load_scenario(SCENARIOS / "rectangle.toml", [
        f"scenario.max_duration_s={RUN_S}", 'runtime.failsafe.thruster_silent="continue"'], 2)
    scn.faults = [FaultSpec(kind="silence", device="thrusters", at_s=15.0 + 1.5 * k,
                            duration_s=1.0) for k in range(6)]
    j = _watched(scn)
    assert not j.unsafe, j.unsafe[:5]
    last_end = 15.0 + 1.5 * 5 + 1.0
    assert [n for _, n in j.entries] == ["thruster_silent"] == [n for _, n in j.clears]
    t_in, t_out = j.entries[0][0], j.clears[0][0]
    assert 15.0 < t_in < 16.0 and last_end + j.fs.clear_after_s <= t_out < last_end + 3.0
    between = [c for c in j.cmds if t_in < c[0] < t_out]
    after = [c for c in j.cmds if t_out + 0.1 < c[0] < t_out + 5.0]
    assert between and all(c[1] == c[2] == 0.0 for c in between)
    assert after and sum(c[1] != 0.0 or c[2] != 0.0 for c in after) > 0.8 * len(after)
