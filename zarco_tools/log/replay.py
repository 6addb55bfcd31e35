"""``zarco log replay FILE``: a recording's inputs through the runtime's estimator and tracker.

The recorded configuration (with ``--set`` changes: a tuning to judge) builds
the runtime on the virtual clock, started at the recorded start time with the
recorded UTC offset.  Its device drivers open ``replay://NAME`` ports
(:class:`ReplayPorts`), and one player task gives the runtime, in the
recording's own order and each at its recorded time, exactly what its
estimator and tracker took in:

* every raw chunk a driver read (``/raw/NAME/rx``), which the unchanged
  drivers frame and parse again into GpsFix, Heading, RateOfTurn,
  AcousticEvent, ...;
* the outputs of the control task as the boat sent them: ThrusterCommand,
  which the navigation EKF takes as its prediction input (and the thruster
  driver writes as ``$PZTHR`` again), ControlStatus, GuidanceStatus and the
  control task's faults;
* the operator's commands and heartbeats, so that the supervisor takes the
  same modes;
* every parameter change the boat accepted (``ParamChange``), applied to the
  replay's configuration at its time, as the supervisor applied it then (the
  ``param`` commands themselves are not played again: the recorded change is
  what happened).

The control task itself does not run (:class:`ReplayRuntime`): the boat moved
under the commands it recorded, and the recorded bytes show that motion, so
commands recomputed from a re-estimated state would be an input the boat
never had, and would make the estimator's input depend on the estimate it is
judged by.  Everything else (drivers, estimator, tracker, supervisor) is the
runtime's own code, as on the boat.

The recording keeps one order of all its records (bus messages and raw
chunks, as the recorder received them; see :func:`load_inputs`).  The player
follows it: a chunk is handed to its driver and the player waits until the
driver has read and parsed it (its next read) before the next input, so
inputs of one instant reach the estimator in the recorded order.  A chunk is
played at the time its driver stamped what it parsed from it (on a real
clock a few microseconds after the raw record's own stamp; on the virtual
clock of a simulation the same time).

So a simulation's recording gives back its navigation (NavState) and AUV
track (AuvFix, AuvTrack) exactly, and a changed setting shows what the change
does on the mission's own data.
"""

from __future__ import annotations

import asyncio
import base64
import dataclasses
import itertools
import math
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

from zarco_core.auv_messages import AuvFix, AuvTrack
from zarco_core.bus import Bus
from zarco_core.clock import Clock, VirtualTimeEventLoop
from zarco_core.commands import CommandRefused, decode
from zarco_core.component import ComponentContext, Runnable
from zarco_core.config import apply_overrides, build
from zarco_core.messages import (
    Command,
    ControlStatus,
    Fault,
    GuidanceStatus,
    NavState,
    OperatorHeartbeat,
    ParamChange,
    ParamValue,
    ThrusterCommand,
)
from zarco_runtime.runtime import Runtime
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.supervision.params import ParamRefused
from zarco_runtime.supervision.params import apply as apply_param
from zarco_runtime.supervision.supervisor import Boot, mission_from_json
from zarco_tools.log.reader import Recording, iter_messages, rebuild

#: what the control task publishes: played as recorded (a Fault only if its own)
CONTROL = {"/ThrusterCommand": ThrusterCommand, "/ControlStatus": ControlStatus,
           "/GuidanceStatus": GuidanceStatus, "/Fault": Fault}
#: operator inputs, published again at their times
OPERATOR = {"/Command": Command, "/OperatorHeartbeat": OperatorHeartbeat,
            "/ParamChange": ParamChange}
PLAYED = {**CONTROL, **OPERATOR}
#: what is compared with the recording
COMPARED = {"/NavState": NavState, "/AuvFix": AuvFix, "/AuvTrack": AuvTrack}
#: topics of what the device drivers publish from the bytes they read (each
#: carries the time the driver stamped on the chunk it parsed)
PARSED = frozenset({"/GpsFix", "/GpsVelocity", "/GpsErrorStats", "/GpsTime", "/Heading",
                    "/RateOfTurn", "/Attitude", "/AcousticEvent", "/BuoyStatus",
                    "/ThrusterStatus"})
#: a parse time this much after its chunk's raw stamp is not believed (s)
PARSE_WITHIN_S = 0.5
#: loop turns the replay lets pass after its last input before it stops
END_SPINS = 20


class ReplayLink:
    """The runtime's end of a replayed device port.

    :meth:`read` hands over the chunks :meth:`feed` gave, one per read (the
    recorded chunk boundaries); :meth:`taken` waits until the reader has
    come back for more (it has parsed everything before: a driver parses a
    chunk before it reads again) or the port was closed.  What the runtime
    writes is kept in ``written`` with its time.
    """

    def __init__(self, name: str, written: list[tuple[float, bytes]]) -> None:
        self.url = f"replay://{name}"
        self.chunks: deque[bytes] = deque()
        self.written = written
        self.closed = False
        self.opened = False
        self._waiter: asyncio.Future[None] | None = None
        self._taken: asyncio.Future[None] | None = None
        self.lost = 0  # chunks fed but not read before the port closed

    def feed(self, data: bytes) -> None:
        self.chunks.append(data)
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)

    async def taken(self) -> None:
        if self.closed:
            return
        if self._taken is None or self._taken.done():
            self._taken = asyncio.get_running_loop().create_future()
        await self._taken

    def _idle(self) -> None:
        f = self._taken
        if f is not None and not f.done():
            f.set_result(None)

    async def read(self) -> bytes:
        while not self.chunks:
            if self.closed:
                return b""
            self._idle()
            self._waiter = asyncio.get_running_loop().create_future()
            try:
                await self._waiter
            finally:
                self._waiter = None
        return self.chunks.popleft()

    async def write(self, data: bytes) -> None:
        self.write_nowait(data)

    def write_nowait(self, data: bytes) -> None:
        if self.closed:
            from drivers.transports import TransportError

            raise TransportError(f"{self.url}: closed")
        self.written.append((asyncio.get_running_loop().time(), data))

    async def close(self) -> None:
        self.closed = True
        self.lost += len(self.chunks)
        self.chunks.clear()
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)
        self._idle()


class ReplayPorts:
    """Port backend of a replay: ``replay://NAME``, one :class:`ReplayLink` at a time
    per device (a port closed and opened again gets a fresh one)."""

    schemes: tuple[str, ...] = ("replay",)

    def __init__(self) -> None:
        self.links: dict[str, ReplayLink] = {}
        self.written: dict[str, list[tuple[float, bytes]]] = {}
        self.lost: Counter[str] = Counter()

    def link(self, name: str) -> ReplayLink:
        """The device's open link, or the one its next opening will get."""
        ln = self.links.get(name)
        if ln is None or ln.closed:
            if ln is not None:
                self.lost[name] += ln.lost
            ln = self.links[name] = ReplayLink(name, self.written.setdefault(name, []))
        return ln

    async def open(self, url: str, baudrate: int) -> ReplayLink:
        from drivers.transports import TransportError

        if not url.startswith("replay://"):
            raise TransportError(f"{url}: a replay opens only replay:// ports")
        name = url[len("replay://"):]
        ln = self.link(name)
        if ln.opened:  # opened again while open: a fresh link
            ln.closed = True
            ln = self.link(name)
        ln.opened = True
        return ln


class _NoControl:
    """Stands in for the control task in a replay: the player publishes the
    control task's recorded outputs instead."""

    async def run(self) -> None:
        await asyncio.Event().wait()


class ReplayRuntime(Runtime):
    """The runtime of a replay: the boat's, but for the control task (its outputs
    are the recording's)."""

    def _make_control(self, ctx: ComponentContext) -> Runnable:
        return _NoControl()


def replay_config(rec: Recording, overrides: list[str], record: str | None) -> RuntimeConfig:
    """The recorded configuration, made to run here: devices on ``replay://``, no
    corrections source, no state file, control socket or links; ``overrides``
    applied (``--set KEY=VALUE``, KEY as in the vessel configuration, with or
    without a ``runtime.`` prefix)."""
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
        apply_overrides(data, [o.removeprefix("runtime.") for o in overrides], file="--set")
    return build(RuntimeConfig, data, f"{rec.paths[0]} (recorded configuration)")


def _param_value(v: Any) -> ParamValue:
    out: ParamValue = [list(map(float, p)) for p in v] if isinstance(v, list) else v
    return out


def command_from_json(d: dict[str, Any]) -> Command | None:
    """A recorded command with its typed arguments (None if they no longer decode:
    a recording of an older runtime)."""
    try:
        name = str(d["name"])
        args = decode(name, d.get("args") or {})
        return Command(float(d["t"]), str(d["id"]), str(d["source"]), name, args)
    except (CommandRefused, KeyError, TypeError, ValueError):
        return None


def _prune(d: Any) -> Any:
    """Drop nulls (a default stands for them: NaN/inf cannot be written as JSON)."""
    if isinstance(d, dict):
        return {k: _prune(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [_prune(v) for v in d]
    return d


@dataclass(slots=True)
class Inputs:
    """What a replay plays, and what it is compared with.

    ``events``: (time, device, chunk) for a raw chunk a driver read, or
    (time, "", message) for a bus message to publish, in the recording's order.
    """

    events: list[tuple[float, str, Any]] = field(default_factory=list)
    recorded: dict[str, list[Any]] = field(default_factory=lambda: {k: [] for k in COMPARED})
    thruster_tx: list[tuple[float, bytes]] = field(default_factory=list)
    commands: list[ThrusterCommand] = field(default_factory=list)
    counts: Counter[str] = field(default_factory=Counter)
    #: the time of the last record of the recording
    t_last: float = -math.inf
    #: raw chunks played at their driver's parse stamp instead of their own
    restamped: int = 0
    #: largest such shift (s)
    restamp_max_s: float = 0.0


def load_inputs(rec: Recording) -> Inputs:
    """The replay's inputs, read in one pass in the recording's order.

    The recorder appends bus messages (as they are published) and raw chunks
    (as drivers read or write them) to one list and writes them in that order:
    the order of a file's records is the order in which the runtime took them
    in.  Inputs are played in it; they are only re-sorted (stably) by time
    when a file's order disagrees with their times.
    """
    out = Inputs()
    events = out.events
    pending: dict[str, int] = {}  # device → its last chunk, until its parse shows
    b64 = base64.b64decode
    last_ns = 0
    for m in iter_messages(rec):
        topic = m.topic
        if m.schema == "zarco.RawChunk":
            d = m.json()
            t, dev = float(d["t"]), str(d["device"])
            out.t_last = max(out.t_last, t)
            if d["dir"] == "rx":
                pending = {dev: len(events)}  # a driver parses a chunk before it reads again
                events.append((t, dev, b64(d["data"])))
                out.counts[f"rx:{dev}"] += 1
            elif dev == "thrusters":
                out.thruster_tx.append((t, b64(d["data"])))
            continue
        if topic not in PLAYED and topic not in COMPARED and topic not in PARSED:
            last_ns = max(last_ns, m.log_ns)
            continue
        d = m.json()
        t = float(d["t"])
        out.t_last = max(out.t_last, t)
        if topic in PARSED:
            src = str(d.get("source", "thrusters"))
            k = pending.pop(src, None)
            if k is not None:
                t0, dev, data = events[k]
                if t != t0 and t0 < t <= t0 + PARSE_WITHIN_S:
                    events[k] = (t, dev, data)
                    out.restamped += 1
                    out.restamp_max_s = max(out.restamp_max_s, t - t0)
        elif topic in COMPARED:
            out.recorded[topic].append(rebuild(COMPARED[topic], d))
        elif topic == "/ParamChange":
            events.append((t, "", ParamChange(t, str(d["name"]), _param_value(d["value"]),
                                              _param_value(d["old"]), str(d.get("source", "")),
                                              str(d.get("id", "")))))
            out.counts[topic] += 1
        elif topic == "/Command":
            cmd = command_from_json(d)
            if cmd is not None and cmd.name != "param":
                events.append((t, "", cmd))
                out.counts[topic] += 1
        elif topic != "/Fault" or d.get("source") == "control":
            msg: Any = rebuild(PLAYED[topic], d)
            events.append((t, "", msg))
            out.counts[topic] += 1
            if topic == "/ThrusterCommand":
                out.commands.append(msg)
    if last_ns:  # the others' times, from their UTC log times (to the microsecond)
        out.t_last = max(out.t_last, last_ns * 1e-9 - rec.utc_offset_s)
    if any(b[0] < a[0] for a, b in itertools.pairwise(events)):
        events.sort(key=lambda e: e[0])
        out.counts["resorted"] = 1
    return out


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
    inputs: dict[str, int] = field(default_factory=dict)
    #: inputs played after their recorded time (a driver not reading then)
    late: int = 0
    #: chunks fed to a port that closed before its driver read them
    lost: int = 0
    restamped: int = 0
    restamp_max_s: float = 0.0
    #: the thruster commands recorded, and those the replay's estimator took
    recorded_commands: list[ThrusterCommand] = field(default_factory=list)
    commands: list[ThrusterCommand] = field(default_factory=list)
    #: a recording cut short (its writer killed): the time of its last input
    cut_t: float | None = None
    #: of ``wall_seconds``, the time spent reading the recording (s)
    read_seconds: float = 0.0
    #: recorded parameter changes this replay's configuration refused (with --set)
    params_refused: list[str] = field(default_factory=list)
    #: why recording the replay (``--record``) stopped, if it did
    record_error: str | None = None

    @property
    def speed(self) -> float:
        return self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else math.inf


def replay(rec: Recording, overrides: list[str] | None = None,
           record: str | None = None) -> ReplayResult:
    """Replay ``rec`` through the runtime built from its configuration."""
    w0 = time.perf_counter()
    cfg = replay_config(rec, overrides or [], record)
    inp = load_inputs(rec)
    read_s = time.perf_counter() - w0
    events = inp.events
    boot_d = rec.boot
    mission = boot_d.get("mission")
    boot = Boot(mission_from_json(mission) if mission else None, bool(boot_d.get("autostart")))
    replayed: dict[str, list[Any]] = {k: [] for k in COMPARED}
    commands: list[ThrusterCommand] = []
    ports = ReplayPorts()
    start = min(rec.t0, events[0][0]) if events else rec.t0
    t_end = max(inp.t_last, start)
    late = [0]
    refused_params: list[str] = []
    record_errors: list[str] = []

    async def main() -> float:
        loop = asyncio.get_running_loop()
        assert isinstance(loop, _ReplayLoop)
        bus = Bus()
        clock = Clock(utc_offset_s=rec.utc_offset_s)
        for topic, kind in COMPARED.items():
            bus.listen(kind, replayed[topic].append)
        bus.listen(ThrusterCommand, commands.append)
        bus.listen(Fault, lambda f: record_errors.append(f.reason)
                   if f.source == "recorder" else None)
        runtime = ReplayRuntime(cfg, bus, clock, ports, boot)

        async def at(t: float) -> None:
            if t > loop.time():
                fut = loop.create_future()
                loop.call_at(t, fut.set_result, None)
                await fut
                loop.set_time(t)  # exactly t, as the recorded runtime saw it

        async def player() -> None:
            publish = bus.publish
            link = ports.link
            for t, dev, item in events:
                if t > loop.time():
                    await at(t)
                elif t < loop.time():
                    late[0] += 1
                if dev:
                    ln = link(dev)
                    ln.feed(item)
                    await ln.taken()
                else:
                    if isinstance(item, ParamChange):
                        try:
                            apply_param(cfg, item.name, item.value)
                        except ParamRefused as exc:  # a --set made it invalid here
                            refused_params.append(str(exc))
                    publish(item)
            await at(t_end)
            for _ in range(END_SPINS):  # what else happens at the last instant
                await asyncio.sleep(0)
            raise _Done

        try:
            async with asyncio.TaskGroup() as tg:
                tg.create_task(runtime.run())
                tg.create_task(player())
        except* _Done:
            pass
        return clock.now()

    loop = _ReplayLoop(start=start)
    try:
        asyncio.set_event_loop(loop)
        end = loop.run_until_complete(main())
    finally:
        asyncio.set_event_loop(None)
        loop.close()
    wall = time.perf_counter() - w0
    lost = sum(ports.lost.values()) + sum(ln.lost for ln in ports.links.values())
    n_chunks = sum(v for k, v in inp.counts.items() if k.startswith("rx:"))
    # a recording cut short may lack the outputs of its last inputs
    cut = bool(rec.truncated) or not all(rec.finished.values())
    cut_t = (events[-1][0] if events else inp.t_last) if cut else None
    return ReplayResult(cfg, inp.recorded, replayed, n_chunks, end - start, wall,
                        ports.written.get("thrusters", []), inp.thruster_tx,
                        dict(inp.counts), late[0], lost, inp.restamped, inp.restamp_max_s,
                        inp.commands, commands, cut_t, read_s, refused_params,
                        record_errors[0] if record_errors else None)


class _Done(Exception):
    pass


class _ReplayLoop(VirtualTimeEventLoop):
    """The virtual loop, whose time a replay can set to a recorded instant exactly.

    The loop runs a timer due within its clock resolution (1 ns) of now without
    moving its clock to the timer's time, so a chunk recorded a few ulps after
    the one before would otherwise be read at that one's time."""

    def set_time(self, t: float) -> None:
        if t > self._vt:
            self._vt = t


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        # JSON carries NaN and ±inf alike as null (read back as NaN)
        return a == b or (not math.isfinite(a) and not math.isfinite(b))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def compare(recorded: list[Any], replayed: list[Any],
            cut_t: float | None = None) -> dict[str, Any]:
    """How a replayed message stream differs from the recorded one: counts, the
    messages not identical field by field, and the largest difference of each
    numeric field.  With ``cut_t`` (a recording cut short at that time), the
    replayed messages of that instant and later beyond the recorded ones are
    left out: their records may be what the cut lost."""
    after_cut = 0
    if cut_t is not None:
        while len(replayed) - after_cut > len(recorded) and replayed[-1 - after_cut].t >= cut_t:
            after_cut += 1
        replayed = replayed[:len(replayed) - after_cut]
    n = min(len(recorded), len(replayed))
    differ = 0
    first = -1
    max_diff: dict[str, float] = {}
    for i, (a, b) in enumerate(zip(recorded[:n], replayed[:n], strict=True)):
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
        if not same:
            differ += 1
            if first < 0:
                first = i
    return {"recorded": len(recorded), "replayed": len(replayed), "compared": n,
            "identical": n - differ, "different": differ,
            "exact": differ == 0 and len(recorded) == len(replayed),
            "first_difference_t": (float(recorded[first].t) if first >= 0 else None),
            **({"after_cut": after_cut} if cut_t is not None else {}),
            "max_diff": {k: float(f"{v:.6g}") for k, v in sorted(max_diff.items())}}


def report(res: ReplayResult) -> dict[str, Any]:
    cut = res.cut_t
    nav = compare(res.recorded["/NavState"], res.replayed["/NavState"], cut)
    pos = _position_diff(res.recorded["/NavState"], res.replayed["/NavState"])
    return {
        "chunks": res.chunks, "sim_seconds": round(res.sim_seconds, 3),
        "wall_seconds": round(res.wall_seconds, 3), "speed_x_realtime": round(res.speed, 1),
        "read_seconds": round(res.read_seconds, 3),
        "inputs": res.inputs, "late": res.late, "lost": res.lost,
        "params_applied": res.inputs.get("/ParamChange", 0) - len(res.params_refused),
        "params_refused": res.params_refused,
        "restamped": res.restamped, "restamp_max_s": float(f"{res.restamp_max_s:.3g}"),
        "cut_short": cut is not None,
        "nav": {**nav, **pos},
        "auv_fix": compare(res.recorded["/AuvFix"], res.replayed["/AuvFix"], cut),
        "auv_track": compare(res.recorded["/AuvTrack"], res.replayed["/AuvTrack"], cut),
        "thruster_commands": compare(res.recorded_commands, res.commands),
        "thruster_bytes": _tx_compare(res.recorded_thruster_tx, res.thruster_tx),
    }


def _tx_compare(rec: list[tuple[float, bytes]],
                rep: list[tuple[float, bytes]]) -> dict[str, Any]:
    """The ``$PZTHR`` bytes the replay's thruster driver wrote against the recorded
    ones.  On a simulation's recording they are the same; on a real run the
    driver's own zeros (its watchdog, before its port opened, its last words
    when killed) differ with the timing of the port and of the process."""
    return {"recorded": len(rec), "replayed": len(rep),
            "identical": [d for _t, d in rec] == [d for _t, d in rep]}


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
