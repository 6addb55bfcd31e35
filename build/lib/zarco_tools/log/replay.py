"""``zarco log replay FILE``: a recording's raw device bytes through the runtime again.

The recorded configuration (with ``--set`` changes: a tuning to judge) builds
an unchanged :class:`~zarco_runtime.runtime.Runtime` on the virtual clock,
started at the recorded start time with the recorded UTC offset.  Its device
drivers open ``replay://NAME`` ports (:class:`ReplayPorts`) at which one
player task writes every recorded ``rx`` chunk at its recorded runtime time,
as the devices did; what the runtime writes back (thruster commands) is kept.
Operator inputs recorded on the bus (commands, heartbeats) are published
again at their times, so the supervisor takes the same modes.

The drivers, the estimator and the tracker then see the same bytes at the
same times: a simulation's recording gives back its navigation (NavState)
and AUV track (AuvFix, AuvTrack) exactly, and with changed settings shows
what the change does on the mission's own data.
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

from drivers.transports import MemoryTransport, Transport, TransportError, memory_link
from zarco_core.auv_messages import AuvFix, AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock, VirtualTimeEventLoop
from zarco_core.config import apply_overrides, build
from zarco_core.messages import Command, NavState, OperatorHeartbeat
from zarco_runtime.runtime import Runtime
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.supervision.supervisor import Boot, mission_from_json
from zarco_tools.log.reader import Recording, iter_messages, rebuild

#: bus messages published again at their recorded times (operator inputs)
REINJECT = {"/Command": Command, "/OperatorHeartbeat": OperatorHeartbeat}
#: what is compared with the recording
COMPARED = {"/NavState": NavState, "/AuvFix": AuvFix, "/AuvTrack": AuvTrack}
#: the replay runs this long after the last recorded chunk (s)
TAIL_S = 0.5


class ReplayPorts:
    """Port backend of a replay: ``replay://NAME`` in-memory links, one per device."""

    schemes: tuple[str, ...] = ("replay",)

    def __init__(self) -> None:
        self.links: dict[str, tuple[MemoryTransport, MemoryTransport]] = {}
        self.written: dict[str, list[tuple[float, bytes]]] = {}
        self.clock: Clock | None = None

    def device_end(self, name: str) -> MemoryTransport:
        if name not in self.links:
            self._create(name)
        return self.links[name][0]

    def _create(self, name: str) -> None:
        dev, rt = memory_link(name)
        log = self.written.setdefault(name, [])
        clock = self.clock
        dev.on_receive(lambda data: log.append((clock.now() if clock else 0.0, data)))
        self.links[name] = (dev, rt)

    async def open(self, url: str, baudrate: int) -> Transport:
        if not url.startswith("replay://"):
            raise TransportError(f"{url}: a replay opens only replay:// ports")
        name = url[len("replay://"):]
        if name not in self.links or self.links[name][1]._rx.closed:
            self._create(name)  # first open, or reopened after a close: a fresh link
        return self.links[name][1]


def replay_config(rec: Recording, overrides: list[str], record: str | None) -> RuntimeConfig:
    """The recorded configuration, made to run here: devices on ``replay://``, no
    corrections source, no state file, control socket or links; ``overrides``
    applied (``--set``)."""
    data = _prune(rec.config)
    for name, dev in data.get("devices", {}).items():
        dev["url"] = f"replay://{name}"
        dev["corrections_url"] = ""
    data.setdefault("supervisor", {}).update(state_file="", control_socket="")
    for link in ("shore", "mavlink"):
        if isinstance(data.get(link), dict):
            data[link]["enabled"] = False
    data["record"] = {**data.get("record", {}), "enabled": bool(record), "file": record or ""}
    if overrides:
        apply_overrides(data, overrides, file="--set")
    return build(RuntimeConfig, data, f"{rec.paths[0]} (recorded configuration)")


def _prune(d: Any) -> Any:
    """Drop nulls (a default stands for them: NaN/inf cannot be written as JSON)."""
    if isinstance(d, dict):
        return {k: _prune(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [_prune(v) for v in d]
    return d


@dataclass(slots=True)
class ReplayResult:
    cfg: RuntimeConfig
    recorded: dict[str, list[Any]]
    replayed: dict[str, list[Any]]
    chunks: int
    sim_seconds: float
    wall_seconds: float
    thruster_tx: list[tuple[float, bytes]] = field(default_factory=list)
    recorded_thruster_tx: list[tuple[float, bytes]] = field(default_factory=list)

    @property
    def speed(self) -> float:
        return self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else math.inf


def _load(rec: Recording) -> tuple[list[tuple[float, str, bytes]],
                                   list[tuple[float, str, Any]],
                                   dict[str, list[Any]], list[tuple[float, bytes]]]:
    import base64

    chunks: list[tuple[float, str, bytes]] = []
    inputs: list[tuple[float, str, Any]] = []
    recorded: dict[str, list[Any]] = {k: [] for k in COMPARED}
    tx: list[tuple[float, bytes]] = []
    for m in iter_messages(rec):
        if m.schema == "zarco.RawChunk":
            d = m.json()
            if d["dir"] == "rx":
                chunks.append((float(d["t"]), str(d["device"]), base64.b64decode(d["data"])))
            elif d["device"] == "thrusters":
                tx.append((float(d["t"]), base64.b64decode(d["data"])))
        elif m.topic in REINJECT:
            d = m.json()
            inputs.append((float(d["t"]), m.topic, d))
        elif m.topic in COMPARED:
            recorded[m.topic].append(rebuild(COMPARED[m.topic], m.json()))
    # stable: chunks of one instant keep the order the drivers read them in
    chunks.sort(key=lambda c: c[0])
    inputs.sort(key=lambda c: c[0])
    return chunks, inputs, recorded, tx


def replay(rec: Recording, overrides: list[str] | None = None,
           record: str | None = None) -> ReplayResult:
    """Replay ``rec`` through the runtime built from its configuration."""
    cfg = replay_config(rec, overrides or [], record)
    chunks, inputs, recorded, rec_tx = _load(rec)
    boot_d = rec.boot
    mission = boot_d.get("mission")
    boot = Boot(mission_from_json(mission) if mission else None, bool(boot_d.get("autostart")))
    replayed: dict[str, list[Any]] = {k: [] for k in COMPARED}
    ports = ReplayPorts()
    t_end = (chunks[-1][0] if chunks else rec.t0) + TAIL_S

    async def main() -> float:
        bus = Bus()
        clock = Clock(utc_offset_s=rec.utc_offset_s)
        ports.clock = clock
        for topic, kind in COMPARED.items():
            bus.listen(kind, replayed[topic].append)
        runtime = Runtime(cfg, bus, clock, ports, boot)
        for name, d in cfg.devices.items():
            if d.enabled:
                ports.device_end(name)

        async def at(t: float) -> None:
            loop = asyncio.get_running_loop()
            if t > loop.time():
                fut = loop.create_future()
                loop.call_at(t, fut.set_result, None)  # exactly t: no float drift
                await fut

        async def player() -> None:
            pending: set[str] = set()
            last_t = -math.inf
            for t, dev, data in chunks:
                if t != last_t:
                    await at(t)
                    pending.clear()
                    last_t = t
                elif dev in pending:
                    await asyncio.sleep(0)  # let the driver read the one before
                    pending.clear()
                ports.device_end(dev).write_nowait(data)
                pending.add(dev)

        async def operator() -> None:
            for t, topic, d in inputs:
                await at(t)
                bus.publish(rebuild(REINJECT[topic], d))

        async def stop() -> None:
            await at(t_end)
            raise _Done

        try:
            async with asyncio.TaskGroup() as tg:
                tg.create_task(runtime.run())
                tg.create_task(player())
                tg.create_task(operator())
                tg.create_task(stop())
        except* _Done:
            pass
        return clock.now()

    w0 = time.perf_counter()
    loop = VirtualTimeEventLoop(start=rec.t0)
    try:
        asyncio.set_event_loop(loop)
        end = loop.run_until_complete(main())
    finally:
        asyncio.set_event_loop(None)
        loop.close()
    wall = time.perf_counter() - w0
    return ReplayResult(cfg, recorded, replayed, len(chunks), end - rec.t0, wall,
                        ports.written.get("thrusters", []), rec_tx)


class _Done(Exception):
    pass


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        # JSON carries NaN and ±inf alike as null (read back as NaN)
        return a == b or (not math.isfinite(a) and not math.isfinite(b))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def compare(recorded: list[Any], replayed: list[Any]) -> dict[str, Any]:
    """How a replayed message stream differs from the recorded one: counts, the
    messages not identical field by field, and the largest difference of each
    numeric field."""
    n = min(len(recorded), len(replayed))
    differ = 0
    max_diff: dict[str, float] = {}
    for a, b in zip(recorded[:n], replayed[:n], strict=True):
        same = True
        for f in dataclasses.fields(a):
            va, vb = getattr(a, f.name), getattr(b, f.name)
            if _same(va, vb):
                continue
            same = False
            if isinstance(va, (int, float)) and isinstance(vb, (int, float)):
                d = abs(float(va) - float(vb))
                if math.isfinite(d):
                    max_diff[f.name] = max(max_diff.get(f.name, 0.0), d)
        differ += not same
    return {"recorded": len(recorded), "replayed": len(replayed), "compared": n,
            "identical": n - differ, "different": differ,
            "exact": differ == 0 and len(recorded) == len(replayed),
            "max_diff": {k: float(f"{v:.6g}") for k, v in sorted(max_diff.items())}}


def report(res: ReplayResult) -> dict[str, Any]:
    nav = compare(res.recorded["/NavState"], res.replayed["/NavState"])
    pos = _position_diff(res.recorded["/NavState"], res.replayed["/NavState"])
    return {
        "chunks": res.chunks, "sim_seconds": round(res.sim_seconds, 3),
        "wall_seconds": round(res.wall_seconds, 3), "speed_x_realtime": round(res.speed, 1),
        "nav": {**nav, **pos},
        "auv_fix": compare(res.recorded["/AuvFix"], res.replayed["/AuvFix"]),
        "auv_track": compare(res.recorded["/AuvTrack"], res.replayed["/AuvTrack"]),
        "thruster_commands": {
            "recorded": len(res.recorded_thruster_tx), "replayed": len(res.thruster_tx),
            "identical": [d for _t, d in res.recorded_thruster_tx]
            == [d for _t, d in res.thruster_tx]},
    }


def _position_diff(a: list[NavState], b: list[NavState]) -> dict[str, float]:
    """RMS and max horizontal distance between recorded and replayed estimates
    (one for one when there are as many, else matched by time)."""
    if len(a) == len(b):
        pairs = list(zip(a, b, strict=True))
    else:
        bt = {m.t: m for m in b}
        pairs = [(m, o) for m in a if (o := bt.get(m.t)) is not None]
    d = [math.hypot(m.x_m - o.x_m, m.y_m - o.y_m) for m, o in pairs]
    d = [x for x in d if math.isfinite(x)]
    if not d:
        return {"position_rms_m": math.nan, "position_max_m": math.nan}
    return {"position_rms_m": math.sqrt(sum(x * x for x in d) / len(d)),
            "position_max_m": max(d)}
