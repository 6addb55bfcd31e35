"""The supervisor's command path on a real bus, clock and local command sender:
parameters as commands (validated, refused under way where unsafe, applied,
published, told), any exception in handling a command is a refusal and never a
restart, hostile payloads get one refusal each, per-source rate limits, arming
reported in the status with the loaded mission's points, the state file written
off the caller's path."""

from __future__ import annotations

import asyncio
import json
import math
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

import pytest

from zarco_core.bus import Bus
from zarco_core.clock import Clock, run_virtual
from zarco_core.component import ComponentContext
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    CommandAck,
    Event,
    Fault,
    FixQuality,
    Heading,
    NavState,
    ParamChange,
    ThrusterStatus,
    VesselStatus,
)
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.supervision import arming, command_handlers
from zarco_runtime.supervision.local import LocalCommands
from zarco_runtime.supervision.params import NAMES, ParamRefused, apply, param_table
from zarco_runtime.supervision.state_file import SavedMission, StateFile
from zarco_runtime.supervision.supervisor import Supervisor


class Rig:
    """A supervisor on a bus, fed a healthy boat on demand."""

    def __init__(self, cfg: RuntimeConfig | None = None, state: StateFile | None = None) -> None:
        self.bus = Bus()
        self.clock = Clock(utc_offset_s=0.0)
        self.cfg = cfg or RuntimeConfig()
        self.ctx = ComponentContext("supervisor", self.bus, self.clock)
        self.sup = Supervisor(self.cfg, self.bus, self.clock, self.ctx, state=state)
        self.acks: list[CommandAck] = []
        self.events: list[Event] = []
        self.params: list[ParamChange] = []
        self.faults: list[Fault] = []
        self.bus.listen(CommandAck, self.acks.append)
        self.bus.listen(Event, self.events.append)
        self.bus.listen(ParamChange, self.params.append)
        self.bus.listen(Fault, self.faults.append)
        self.local = LocalCommands(self.bus, self.clock, source="test")
        o = self.cfg.origin
        self.frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)

    def healthy(self) -> None:
        t = self.clock.now()
        self.bus.publish(Heading(t, "compass", "HDT", 0.0, True, 0.0))
        self.bus.publish(ThrusterStatus(t, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        self.bus.publish(NavState(t, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 41.0, -8.0,
                                  FixQuality.RTK_FIXED, True, True, (), 0.0))
        self.sup.evaluate(t)

    async def send(self, name: str, args: Any = None, source: str = "test") -> CommandAck:
        return await self.local.send(name, args, source=source)

    def geo(self, n: float, e: float) -> list[float]:
        lat, lon, _ = self.frame.to_geodetic(n, e)
        return [lat, lon]


def _run(body: Callable[[Rig], Coroutine[Any, Any, None]], **kw: Any) -> None:
    async def main() -> None:
        await body(Rig(**kw))

    run_virtual(main())


# ------------------------------------------------------------- parameters


def test_the_registry_lists_every_parameter_with_its_value_and_range() -> None:
    cfg = RuntimeConfig()
    table = param_table(cfg)
    assert [p.name for p in table] == list(NAMES)
    by = {p.name: p for p in table}
    p = by["failsafe.link_lost_s"]
    assert (p.kind, p.lo, p.hi, p.value, p.locked_under_way) == \
        ("float", 0.5, 3600.0, cfg.failsafe.link_lost_s, True)
    assert by["failsafe.link_lost"].choices == ("continue", "hold", "idle", "return")
    assert by["control.speed_kp"].locked_under_way is False
    assert by["geofence.polygon"].kind == "points"
    assert by["supervisor.command_burst"].kind == "int"
    assert by["control.current_feedforward"].kind == "bool"


@pytest.mark.parametrize("name, value, why", [
    ("failsafe.link_lost_s", 0.1, "must be ≥ 0.5 s"),
    ("failsafe.link_lost_s", 1e9, "must be ≤ 3600 s"),
    ("failsafe.link_lost_s", True, "must be a number"),
    ("failsafe.link_lost_s", "ten", "must be a number"),
    ("failsafe.link_lost_s", math.nan, "finite"),
    ("failsafe.link_lost", "panic", "must be one of continue, hold, idle, return"),
    ("failsafe.position_lost", "hold", "needs the position that is lost"),
    ("control.current_feedforward", 1.0, "must be true or false"),
    ("supervisor.command_burst", 2.5, "whole number"),
    ("geofence.polygon", [[41.0, -8.0], [41.1, -8.0]], "at least 3 vertices"),
    ("control.rate_hz", 10.0, "no such parameter"),
    ("vessel.m_kg", 1.0, "no such parameter"),
])
def test_a_bad_parameter_is_refused_with_its_name_and_nothing_changes(
        name: str, value: Any, why: str) -> None:
    cfg = RuntimeConfig()
    before = json.dumps([p.value for p in param_table(cfg)])
    with pytest.raises(ParamRefused) as exc:
        apply(cfg, name, value)
    assert str(exc.value).startswith(name) and why in str(exc.value)
    assert json.dumps([p.value for p in param_table(cfg)]) == before


def test_param_commands_apply_publish_and_tell() -> None:
    async def body(r: Rig) -> None:
        a = await r.send("param", {"name": "failsafe.link_lost_s", "value": 25})
        assert a.ok and r.cfg.failsafe.link_lost_s == 25.0
        (ch,) = r.params
        assert (ch.name, ch.value, ch.old, ch.source, ch.id) == \
            ("failsafe.link_lost_s", 25.0, 10.0, "test", a.id)
        assert any(e.kind == "param" and "failsafe.link_lost_s = 25.0 (was 10.0)" in e.text
                   for e in r.events)
        a = await r.send("param", {"name": "failsafe.link_lost", "value": "idle"})
        assert a.ok and r.cfg.failsafe.link_lost == "idle"
        a = await r.send("param", {"name": "supervisor.command_burst", "value": 7.0})
        assert a.ok and r.cfg.supervisor.command_burst == 7 and \
            isinstance(r.cfg.supervisor.command_burst, int)
        a = await r.send("param", {"name": "failsafe.link_lost_s", "value": "x"})
        assert not a.ok and a.reason == "failsafe.link_lost_s: must be a number"
        assert len(r.params) == 3
    _run(body)


def test_the_failsafe_table_and_geofence_do_not_change_under_way() -> None:
    async def body(r: Rig) -> None:
        r.healthy()
        assert (await r.send("arm")).ok
        assert (await r.send("mode", {"mode": "hold"})).ok
        for name, value in (("failsafe.link_lost", "continue"), ("geofence.radius_m", 5.0),
                            ("failsafe.clear_after_s", 0.0)):
            a = await r.send("param", {"name": name, "value": value})
            assert not a.ok and "do not change under way (mode hold)" in a.reason, a
        gain = await r.send("param", {"name": "hold.k_s", "value": 15.0})
        assert gain.ok and r.cfg.hold.k_s == 15.0  # a gain may change under way
        assert r.cfg.failsafe.link_lost == "hold" and r.cfg.geofence.radius_m == 0.0
        assert (await r.send("stop")).ok
        a = await r.send("param", {"name": "geofence.radius_m", "value": 50.0})
        assert a.ok
        # the new geofence is the supervisor's at once: a mission beyond it is refused
        assert (await r.send("arm")).ok
        m = await r.send("mission", {"waypoints": [r.geo(0, 0), r.geo(80, 0)]})
        assert not m.ok and m.reason.startswith("waypoints[1]: outside the geofence")
    _run(body)


# ------------------------------------------------------------- robustness


@pytest.mark.parametrize("name, payload", [
    ("mission", {"waypoints": [[10 ** 401, 0.0], [0.0, 0.0]]}),
    ("mode", {"mode": "hold", "lat_deg": 10 ** 401, "lon_deg": 0.0}),
    ("thrust", {"u1": 10 ** 401, "u2": 0.0}),
    ("mission", b'{"waypoints": [[41, -8], [41.001, -8]], "start_leg": 1e999}'),
    ("mission", b"[" * 30000),
    ("mission", {"waypoints": [[41.0, -8.0], [41.001, -8.0]], "start": "false"}),
    ("thrust", {"u1": " 1e2 ", "u2": 0.0}),
    ("mission", {"waypoints": "[[41, -8], [42, -8]]"}),
    ("mission", {"waypoints": [[41.0, -8.0], [41.001, -8.0]], "name": "x\x1b[2J" * 20000}),
])
def test_hostile_payloads_get_one_refusal_each_and_restart_nothing(name: str,
                                                                   payload: Any) -> None:
    async def body(r: Rig) -> None:
        r.healthy()
        assert (await r.send("arm")).ok
        n = len(r.acks)
        a = await r.send(name, payload)
        assert not a.ok and a.reason
        assert len(r.acks) == n + 1 and r.ctx.error is None
        assert r.sup.mode.value == "idle"
        assert len(a.reason) < 200 and "\x1b" not in a.reason
    _run(body)


def test_an_error_while_handling_is_a_refusal_and_a_fault_not_a_restart(
        monkeypatch: pytest.MonkeyPatch) -> None:
    async def body(r: Rig) -> None:
        r.healthy()
        assert (await r.send("arm")).ok

        def broken(*_a: object) -> str:
            raise OverflowError("int too large to convert to float")

        monkeypatch.setattr(command_handlers, "mode", broken)
        a = await r.send("mode", {"mode": "hold"})
        assert not a.ok and a.reason == "not handled: internal error (OverflowError)"
        assert r.faults and "OverflowError" in r.faults[-1].reason
        assert r.ctx.error is None  # the listener did not raise: no restart
        r.healthy()
        assert r.sup.snapshot(r.clock.now()).counters["command_faults"] == 1

        def broken_stop(*_a: object) -> None:
            raise RuntimeError("bug in stop")

        monkeypatch.setattr(arming, "disarm", broken_stop)
        s = await r.send("stop")
        assert s.ok and not r.sup.armed and r.sup.mode.value == "idle"  # stop still stops
        assert r.sup.directive.armed is False
    _run(body)


def test_each_source_is_rate_limited_but_stop_always_passes() -> None:
    async def body(r: Rig) -> None:
        r.cfg.supervisor.command_burst = 10
        r.cfg.supervisor.command_rate_hz = 5.0
        acks = [await r.send("resume", source="shore:flood") for _ in range(25)]
        limited = [a for a in acks if a.reason.startswith("rate limited")]
        assert len(limited) == 15 and all(a.reason == "disarmed"
                                          for a in acks[:10])
        assert "from shore:flood" in limited[0].reason
        assert (await r.send("stop", source="shore:flood")).ok
        assert (await r.send("disarm", source="shore:flood")).ok
        other = await r.send("resume", source="shore:calm")  # another source is not limited
        assert other.reason == "disarmed"
        await asyncio.sleep(1.0)  # 5 tokens back
        again = [await r.send("resume", source="shore:flood") for _ in range(6)]
        assert [a.reason.startswith("rate limited") for a in again] == [False] * 5 + [True]
        # the event stream tells a few acknowledgements a second per source, then a count
        told = [e for e in r.events if e.kind == "ack" and "shore:flood" in e.text]
        assert len(told) == 5 + 5  # 33 acknowledgements in two seconds
        over = r.sup.ack_events.overflow(r.clock.now() + 1.0)
        assert over and over[0][0] == "shore:flood" and over[0][1] > 0
    _run(body)


# ------------------------------------------------------------------ status


def test_the_status_carries_arming_and_the_loaded_missions_points() -> None:
    async def body(r: Rig) -> None:
        r.healthy()
        st = r.sup.snapshot(r.clock.now())
        assert st.armed is False and st.mission_points == () and st.mission_id == 0
        wps = [r.geo(0, 0), r.geo(30, 0), r.geo(30, 30)]
        assert (await r.send("mission", {"waypoints": wps, "start": False})).ok
        st = r.sup.snapshot(r.clock.now())
        assert st.mission_points == tuple(tuple(w) for w in wps) and st.mission_id == 1
        assert st.mission_points == r.sup.snapshot(r.clock.now()).mission_points
        assert r.sup.snapshot(r.clock.now()).mission_id == 1  # unchanged: same id
        assert (await r.send("arm")).ok
        assert (await r.send("mode", {"mode": "lines"})).ok
        st = r.sup.snapshot(r.clock.now())
        assert st.armed and st.mode == "lines" and st.mission_id == 1
        assert (await r.send("stop")).ok
        assert (await r.send("mission", {"clear": True})).ok
        st = r.sup.snapshot(r.clock.now())
        assert not st.armed and st.mission_points == () and st.mission_id == 2
    _run(body)


def test_arming_is_published_to_the_control_loop_and_the_status() -> None:
    async def body(r: Rig) -> None:
        seen: list[VesselStatus] = []
        r.bus.listen(VesselStatus, seen.append)
        a = await r.send("arm")
        assert not a.ok and a.reason == "no valid position"
        r.healthy()
        assert (await r.send("arm")).ok
        assert r.sup.directive.armed and r.sup.directive.mode.value == "idle"
        assert any(e.kind == "arming" and e.text == "armed by test" for e in r.events)
        assert (await r.send("disarm")).ok
        assert not r.sup.directive.armed
    _run(body)


@pytest.mark.parametrize("action", ["continue", "hold"])
def test_a_driving_failsafe_is_published_to_the_control_loop_until_it_clears(
        action: str) -> None:
    """From a driving failsafe's entry until it clears (clear_after_s of health,
    not the moment its condition ends) the directive carries it, whatever the
    action: continue keeps the mode, hold changes it; both hold the thrust."""
    cfg = RuntimeConfig()
    cfg.failsafe.thruster_silent = action
    cfg.failsafe.clear_after_s = 1.5

    async def body(r: Rig) -> None:
        r.healthy()
        assert (await r.send("arm")).ok and (await r.send("mode", {"mode": "manual"})).ok
        seq = r.sup.directive.seq
        seen: list[tuple[float, tuple[str, ...], str]] = []

        async def tick(answer: bool) -> None:
            await asyncio.sleep(0.05)
            t = r.clock.now()
            r.bus.publish(Heading(t, "compass", "HDT", 0.0, True, 0.0))
            if answer:
                r.bus.publish(ThrusterStatus(t, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
            r.bus.publish(NavState(t, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 41.0, -8.0,
                                   FixQuality.RTK_FIXED, True, True, (), 0.0))
            r.sup.evaluate(t)
            d = r.sup.directive
            seen.append((t, d.driving_failsafes, d.mode.value))

        t0 = r.clock.now()
        for _ in range(20):  # silent for 1 s
            await tick(False)
        t_back = r.clock.now()
        for _ in range(50):  # answering again for 2.5 s
            await tick(True)
        lim = r.cfg.failsafe.thruster_silent_s
        held = [t for t, fs, _ in seen if fs == ("thruster_silent",)]
        assert held and t0 + lim < held[0] <= t0 + lim + 0.1, held[:2]
        assert t_back + 1.5 <= held[-1] + 0.05 and held[-1] < t_back + 1.6
        assert all(fs == () for t, fs, _ in seen if t < held[0] or t > held[-1])
        assert r.sup.directive.armed
        if r.cfg.failsafe.thruster_silent == "continue":
            assert all(m == "manual" for _, _, m in seen)
            assert r.sup.directive.seq == seq  # the same directive, republished
        else:
            assert all(m == ("hold" if t >= held[0] else "manual") for t, _, m in seen)
    _run(body, cfg=cfg)


# -------------------------------------------------------------- state file


def test_the_state_file_is_written_by_its_task_not_by_the_caller(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "state.json"
    sf = StateFile(str(path))

    async def main() -> None:
        from zarco_runtime.guidance.mission import Leg, Mission

        m = Mission("lines", (Leg(0, 0.0, 0.0, 10.0, 0.0, 1.0),), "m1", ((41.0, -8.0),))
        task = asyncio.ensure_future(sf.run())
        await asyncio.sleep(0)
        sf.save(SavedMission(m, 0), 1.0)
        assert not path.exists()  # save() only hands it over
        for k in range(1, 4):  # a burst: the writer may coalesce, the last one wins
            sf.save(SavedMission(m, k), 1.0 + k)
        for _ in range(200):
            await asyncio.sleep(0.01)
            if path.exists() and json.loads(path.read_text())["leg"] == 3:
                break
        assert json.loads(path.read_text())["leg"] == 3
        assert 1 <= sf.writes <= 4
        sf.save(SavedMission(m, 5, True), 9.0)  # saved, then cancelled: written on the way out
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task

    asyncio.run(main())
    d = json.loads(path.read_text())
    assert d["leg"] == 5 and d["complete"] is True
    again = StateFile(str(path)).load()
    assert again is not None and again.leg == 5 and again.mission.name == "m1"
