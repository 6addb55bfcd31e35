"""``zarco hil SCENARIO.toml``: the unchanged runtime, as on the boat, against the
simulator behind pseudo-terminals, in real time.

1. the simulator (:mod:`hil.simulator`) creates one pseudo-terminal per device
   behind stable links ``RUN/dev/{gps,compass,thrusters}`` (and ``RUN/dev/buoy``
   when the scenario follows the AUV);
2. a runtime configuration pointing at those links, with the scenario's
   ``[runtime]`` and ``[mission]``, is written to ``RUN/zarco.toml``;
3. ``zarco run --config RUN/zarco.toml --status RUN/status.jsonl`` starts as a
   separate process; the rig reads its status file as it grows (status
   snapshots and events: :mod:`hil.runtime_status`) and keeps its stderr in
   ``RUN/runtime.log`` (read for errors only);
4. once the runtime has opened every port and its status lists every device,
   the world clock starts: devices write at their rates, faults are injected
   at their times, the thruster commands read from the thruster port drive
   the world;
5. at the end of the mission (or ``--duration``), the runtime gets SIGTERM
   (it must send zero thrust and exit 0), and the report and plot are written
   like ``zarco sim``'s, measured on the simulator's truth, plus a ``hil``
   section: runtime exit, health transitions, failsafes and mode changes
   (from its status file), replug times, timing (control period jitter and
   GPS → command latency measured at the ports, the control loop's own
   jitter from the status file's final line), runtime CPU and memory.
"""

from __future__ import annotations

import asyncio
import bisect
import contextlib
import dataclasses
import itertools
import json
import math
import os
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from drivers.sim.faults import FaultSpec
from hil.follow import FINAL_S, LEG_SETTLE_S, follow_figures
from hil.runtime_status import ErrorLog, RuntimeStatus
from hil.simulator import HilSimulator
from zarco_core.geodesy import LocalFrame
from zarco_core.paths import writable_dir
from zarco_runtime.guidance.mission import Leg, build_legs
from zarco_tools.scenario import Scenario
from zarco_tools.sim_report import TrackLog, line_figures
from zarco_tools.simulation import command_step_rms

#: how long the runtime may take to open its ports and report its devices (s)
ATTACH_TIMEOUT_S = 30.0
#: how often the runtime's status file is read while it runs (s)
STATUS_POLL_S = 0.2
#: how long the runtime may take to stop after SIGTERM (s)
STOP_TIMEOUT_S = 10.0
#: after the truth reached the mission's end, how long the runtime has to see it too (s)
RUNTIME_SEES_END_S = 3.0
#: a leg counts as "with faults" if it overlaps a fault window widened by this (s)
RECOVERY_MARGIN_S = 5.0
#: resource samples period (s)
SAMPLE_PERIOD_S = 5.0


class HilError(RuntimeError):
    """The rig could not run (the runtime did not start or open its ports)."""


# ---------------------------------------------------------------- config out


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write {v!r} to TOML configuration")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def toml_dumps(data: dict[str, Any], _prefix: str = "") -> str:
    """A nested dict (scalars, lists, tables; None values left out) as TOML."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items()
             if v is not None and not isinstance(v, dict)]
    out = "\n".join(lines) + ("\n" if lines else "")
    for k, v in data.items():
        if isinstance(v, dict):
            name = f"{_prefix}{k}"
            body = toml_dumps(v, name + ".")
            if any(not isinstance(x, dict) for x in v.values() if x is not None) or not v:
                out += f"\n[{name}]\n"
            out += body
    return out


def runtime_config(scn: Scenario, links: dict[str, str]) -> dict[str, Any]:
    """The ``zarco run`` configuration of a HIL run: the scenario's runtime and
    mission, with each device at its pseudo-terminal link."""
    cfg = dataclasses.asdict(scn.runtime)
    for dev, path in links.items():
        cfg["devices"][dev]["url"] = path
    cfg["mission"] = dataclasses.asdict(scn.mission)
    return cfg


def zarco_command() -> list[str]:
    """The ``zarco`` of this installation (the console script beside python)."""
    exe = Path(sys.executable).with_name("zarco")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "zarco_runtime.cli"]


# ------------------------------------------------------------ process stats


def proc_stats(pid: int) -> tuple[float, float] | None:
    """(CPU seconds used, resident MB) of a process, from /proc; None if gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    cpu = (int(fields[11]) + int(fields[12])) / ticks
    rss_kb = next((int(ln.split()[1]) for ln in status.splitlines()
                   if ln.startswith("VmRSS:")), 0)
    return cpu, rss_kb / 1024.0


# ----------------------------------------------------------------- figures


def _pct(a: list[float], q: float) -> float | None:
    return round(float(np.percentile(np.asarray(a), q)), 3) if a else None


def timing_figures(sim: HilSimulator, t_start: float, t_end: float, period_s: float,
                   windows: list[tuple[float, float]]) -> dict[str, Any]:
    """Control period jitter and GPS-write → command latency, measured at the ports.

    Both are seen from the simulator's side of the pseudo-terminals (read
    timestamps of ``$PZTHR``, end of each GPS epoch's write), so they include
    the pty transfer and the simulator's own scheduling: upper bounds of the
    runtime's.  Intervals overlapping a fault window are left out.
    """
    t0 = sim.t0

    def faulty(a: float, b: float) -> bool:
        return any(a - t0 < hi and b - t0 > lo for lo, hi in windows)

    cmds = [c for c in sim.timing.commands if t_start <= c[0] <= t_end]
    times = [c[0] for c in cmds]
    periods = [b - a for a, b in itertools.pairwise(times) if not faulty(a, b)]
    jitter = [abs(p - period_s) * 1000.0 for p in periods]
    lat = []
    for w in sim.timing.gps_writes:
        i = bisect.bisect_right(times, w)
        if i < len(times) and times[i] - w < 0.5 and not faulty(w, times[i]):
            lat.append((times[i] - w) * 1000.0)
    return {
        "commands": len(cmds),
        "period_mean_ms": round(1000.0 * float(np.mean(periods)), 3) if periods else None,
        "jitter_p50_ms": _pct(jitter, 50),
        "jitter_p99_ms": _pct(jitter, 99),
        "jitter_max_ms": round(max(jitter), 3) if jitter else None,
        "latency_samples": len(lat),
        "latency_p50_ms": _pct(lat, 50),
        "latency_p99_ms": _pct(lat, 99),
        "latency_max_ms": round(max(lat), 3) if lat else None,
    }


#: bin width of the runtime's period jitter histogram (control/task.py JITTER_BIN_S)
JITTER_BIN_MS = 0.05


def hist_figures(counts: list[int], bin_ms: float = JITTER_BIN_MS) -> dict[str, Any]:
    """p50 / p99 / max of the runtime's own control period jitter histogram (upper
    bin edges: conservative; the last bin holds everything beyond)."""
    total = sum(counts)
    if not total:
        return {}

    def pct(q: float) -> float:
        need = q / 100.0 * total
        acc = 0
        for i, n in enumerate(counts):
            acc += n
            if acc >= need:
                return round((i + 1) * bin_ms, 3)
        return round(len(counts) * bin_ms, 3)  # pragma: no cover

    top = max(i for i, n in enumerate(counts) if n)
    return {"runtime_periods": total, "runtime_jitter_p50_ms": pct(50),
            "runtime_jitter_p99_ms": pct(99),
            "runtime_jitter_max_ms": round((top + 1) * bin_ms, 3)
            if top < len(counts) - 1 else f">{(len(counts) - 1) * bin_ms:g}"}


def leg_spans(log: TrackLog) -> dict[int, tuple[float, float]]:
    spans: dict[int, tuple[float, float]] = {}
    for t, k in zip(log.t, log.leg, strict=True):
        lo, hi = spans.get(k, (t, t))
        spans[k] = (min(lo, t), max(hi, t))
    return spans


def clean_legs(log: TrackLog, faults: list[FaultSpec],
               margin_s: float = RECOVERY_MARGIN_S) -> list[int]:
    """Legs whose time span overlaps no fault window (widened by ``margin_s``)."""
    out = []
    for k, (lo, hi) in sorted(leg_spans(log).items()):
        if not any(lo < f.end_s + margin_s and hi > f.at_s - margin_s for f in faults):
            out.append(k)
    return out


def pooled_rms(legs: list[dict[str, Any]], which: list[int]) -> float | None:
    """Cross-track RMS over the settled samples of the legs ``which``."""
    num = den = 0
    for leg in legs:
        if leg["leg"] in which and leg["samples"] and math.isfinite(leg["xtrack_rms_m"]):
            num += leg["samples"] * leg["xtrack_rms_m"] ** 2
            den += leg["samples"]
    return math.sqrt(num / den) if den else None


def replug_figures(sim: HilSimulator, rst: RuntimeStatus) -> list[dict[str, Any]]:
    """For each replug: when the runtime opened the port again (seen at the
    master) and when it read a valid sentence again (the device's ``ok`` event
    in its status file)."""
    out = []
    for ev in sim.events:
        if ev.what != "replugged":
            continue
        att = next((e for e in sim.events if e.device == ev.device and e.what == "attached"
                    and e.wall >= ev.wall), None)
        ok = rst.first(ev.device, "ok", ev.wall)
        out.append({
            "device": ev.device, "t": round(ev.t, 3),
            "opened_after_s": round(att.wall - ev.wall, 3) if att else None,
            "read_after_s": round(ok.wall - ev.wall, 3) if ok else None,
        })
    return out


# --------------------------------------------------------------------- run


@dataclasses.dataclass(slots=True)
class HilResult:
    scenario: Scenario
    legs: list[Leg]
    log: TrackLog
    report: dict[str, Any]
    run_dir: Path
    #: the AUV's true track when following: (t, north m, east m, heading rad)
    auv_log: list[tuple[float, float, float, float]] = dataclasses.field(default_factory=list)


class _Status:
    """The running status line on stderr (sim time, leg or distance, device states)."""

    def __init__(self, sim: HilSimulator, rst: RuntimeStatus, limit: float,
                 stream: Any = sys.stderr) -> None:
        self.sim, self.rst, self.limit, self.stream = sim, rst, limit, stream
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self.last = -1e9

    def __call__(self, t: float) -> None:
        now = time.monotonic()
        if now - self.last < (0.5 if self.tty else 10.0):
            return
        self.last = now
        sim = self.sim
        if sim.auv_log and sim.log.t:
            _, ax, ay, _ = sim.auv_log[-1]
            where = f"AUV at {math.hypot(sim.log.x[-1] - ax, sim.log.y[-1] - ay):5.1f} m"
        else:
            where = f"leg {sim.leg + 1}/{len(sim.legs)}"
        mode = self.rst.modes[-1] if self.rst.modes else "?"
        msg = (f"hil {t:7.1f}/{self.limit:.0f} s  {mode}  {where}  "
               + "  ".join(f"{d} {self.rst.state(d)}" for d in sim.devices))
        self.stream.write(("\r" + msg.ljust(78)) if self.tty else (msg + "\n"))
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\r" + " " * 78 + "\r")
            self.stream.flush()


def failsafe_entries(rst: RuntimeStatus) -> list[str]:
    """The failsafes the runtime entered (their event text without the timing)."""
    out = set()
    for ev in rst.of_kind("failsafe"):
        if "; action " in ev.text:
            out.add(ev.text.split(" (condition since", 1)[0])
    return sorted(out)


class _Signals:
    """SIGTERM, SIGINT and SIGHUP while the rig runs: the first ends the run as its
    end would (the runtime is stopped, zero thrust checked, the report written);
    a second one while stopping kills the runtime at once.  Either way the
    runtime never outlives the rig."""

    SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.first = asyncio.Event()
        self.name = ""
        self.proc: asyncio.subprocess.Process | None = None
        for sig in self.SIGNALS:
            loop.add_signal_handler(sig, self._on, sig)

    def _on(self, sig: signal.Signals) -> None:
        if not self.first.is_set():
            self.name = sig.name
            self.first.set()
            print(f"\nzarco hil: {sig.name}: stopping the runtime (again to kill it)",
                  file=sys.stderr, flush=True)
        elif self.proc is not None and self.proc.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.kill()

    def close(self) -> None:
        for sig in self.SIGNALS:
            self.loop.remove_signal_handler(sig)


def _die_with_parent() -> Callable[[], None] | None:
    """A function to run in the runtime's process before it starts (Linux): it
    then gets SIGTERM when the rig's process ends, however it ends (even
    SIGKILL), so that no runtime is left holding the pseudo-terminals.  The
    C function is looked up here, in the rig: the child only calls it."""
    import ctypes

    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    pr_set_pdeathsig, term = 1, int(signal.SIGTERM)

    def child() -> None:  # pragma: no cover - runs in the child, before exec
        prctl(pr_set_pdeathsig, term)

    return child


async def _run(scn: Scenario, faults: list[FaultSpec], legs: list[Leg], run_dir: Path,
               limit_s: float, quiet: bool) -> dict[str, Any]:
    loop = asyncio.get_running_loop()
    signals = _Signals(loop)
    try:
        return await _run_rig(scn, faults, legs, run_dir, limit_s, quiet, signals)
    finally:
        signals.close()


async def _run_rig(scn: Scenario, faults: list[FaultSpec], legs: list[Leg], run_dir: Path,
                   limit_s: float, quiet: bool, signals: _Signals) -> dict[str, Any]:
    loop = asyncio.get_running_loop()
    sim = HilSimulator(scn, faults, legs, run_dir)
    status_file = run_dir / "status.jsonl"
    status_file.unlink(missing_ok=True)  # the runtime appends: one run per file
    rst = RuntimeStatus(status_file)
    errlog = ErrorLog()
    sim.plug_all()
    watch = loop.create_task(sim.watch_ports(), name="hil.ports")
    cfg_path = run_dir / "zarco.toml"
    cfg_path.write_text("# written by zarco hil: the scenario's runtime and mission, with the "
                        "devices on pseudo-terminals\n"
                        + toml_dumps(runtime_config(scn, sim.links)))
    cmd = [*zarco_command(), "run", "--config", str(cfg_path), "--status", str(status_file)]
    logf = (run_dir / "runtime.log").open("w")
    w_spawn = time.monotonic()
    proc = await asyncio.create_subprocess_exec(
        *cmd, stdin=asyncio.subprocess.DEVNULL, stdout=logf, stderr=asyncio.subprocess.PIPE,
        start_new_session=True, preexec_fn=_die_with_parent())
    signals.proc = proc

    async def pump() -> None:
        assert proc.stderr is not None
        async for raw in proc.stderr:
            text = raw.decode("utf-8", "replace")
            logf.write(text)
            errlog.feed(text)

    async def read_status() -> None:
        while True:
            rst.poll()
            await asyncio.sleep(STATUS_POLL_S)

    async def ready() -> bool:
        """The runtime has every port open and its status lists every device."""
        end = loop.time() + ATTACH_TIMEOUT_S
        if not await sim.wait_attached(ATTACH_TIMEOUT_S):
            return False
        while not rst.ready(sim.devices):
            if loop.time() > end:
                return False
            await asyncio.sleep(0.02)
            rst.poll()
        return True

    pumping = loop.create_task(pump(), name="hil.runtime-log")
    reading = loop.create_task(read_status(), name="hil.runtime-status")
    exited = loop.create_task(proc.wait(), name="hil.runtime-exit")
    samples: list[tuple[float, float, float]] = []
    tasks: list[asyncio.Task[Any]] = []
    status = None if quiet else _Status(sim, rst, limit_s)
    interrupted = loop.create_task(signals.first.wait(), name="hil.signals")
    try:
        attach = loop.create_task(ready())
        await asyncio.wait({attach, exited, interrupted}, return_when=asyncio.FIRST_COMPLETED)
        if signals.first.is_set() and not (attach.done() and attach.result()):
            attach.cancel()
            raise HilError(f"{signals.name} before the run started: runtime stopped")
        if not attach.done() or not attach.result():
            attach.cancel()
            await asyncio.sleep(0.1)  # its last words
            tail = "\n".join((run_dir / "runtime.log").read_text().splitlines()[-5:]) \
                if (run_dir / "runtime.log").exists() else ""
            missing = [d for d, a in sim.attached.items() if not a]
            why = (f"exited with code {proc.returncode}" if exited.done()
                   else f"did not open {missing} within {ATTACH_TIMEOUT_S:g} s" if missing
                   else f"did not report its devices in {status_file.name} within "
                        f"{ATTACH_TIMEOUT_S:g} s")
            raise HilError(f"runtime {why}\n{tail}")
        startup_s = time.monotonic() - w_spawn
        wall0 = time.time()
        sim.progress = status
        tasks = sim.start()
        t_start = loop.time()

        async def sampler() -> None:
            while True:
                st = proc_stats(proc.pid)
                if st is not None:
                    samples.append((loop.time() - t_start, *st))
                await asyncio.sleep(SAMPLE_PERIOD_S)

        tasks.append(loop.create_task(sampler(), name="hil.sampler"))
        done = loop.create_task(sim.complete.wait())
        finished, _ = await asyncio.wait({done, exited, interrupted}, timeout=limit_s,
                                         return_when=asyncio.FIRST_COMPLETED)
        done.cancel()
        t_end = loop.time()
        end_stats = proc_stats(proc.pid)
        if end_stats is not None:
            samples.append((t_end - t_start, *end_stats))
        if exited in finished:
            stop = f"runtime exited (code {proc.returncode})"
        elif interrupted in finished:
            stop = f"signal {signals.name}"
        elif done in finished:
            stop = "mission complete"
        else:
            stop = f"time limit {limit_s:g} s"
        sim.recording = False
        sim_seconds = sim.now()
        if done in finished:
            # the rig judges the end on the truth, the runtime on its estimate: give
            # it a moment to see the end too (its mode leaves lines) before the stop
            see_by = loop.time() + RUNTIME_SEES_END_S
            while loop.time() < see_by and not exited.done() and rst.modes[-1:] == ["lines"]:
                await asyncio.sleep(STATUS_POLL_S / 4)
                rst.poll()
        # shutdown: the runtime must write zero thrust and exit cleanly
        n_cmds = len(sim.timing.commands)
        early_exit = exited.done()
        if not early_exit:
            proc.send_signal(signal.SIGTERM)
        try:
            await asyncio.wait_for(asyncio.shield(exited), STOP_TIMEOUT_S)
        except TimeoutError:
            proc.kill()
            await exited
        await asyncio.sleep(0.05)
        after = sim.timing.commands[n_cmds:]
        last = sim.timing.commands[-1][1:] if sim.timing.commands else None
    finally:
        for t in tasks:
            t.cancel()
        interrupted.cancel()
        watch.cancel()
        reading.cancel()
        if proc.returncode is None:  # interrupted: stop it as on the boat, then for good
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(signal.SIGTERM)
            try:
                await asyncio.wait_for(asyncio.shield(exited), 3.0)
            except (TimeoutError, asyncio.CancelledError):
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
                await exited
        sim.close()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(pumping, 2.0)
        logf.close()
        if status is not None:
            status.close()
    rst.poll()  # the rest, with the final line

    period = 1.0 / scn.runtime.control.rate_hz
    windows = [(f.at_s, f.end_s) for f in faults]
    timing = timing_figures(sim, t_start, t_end, period, windows)
    cpu = rss0 = rss1 = None
    if len(samples) >= 2:
        (ta, ca, rss0), (tb, cb, rss1) = samples[0], samples[-1]
        cpu = round(100.0 * (cb - ca) / (tb - ta), 2) if tb > ta else None
    replugs = replug_figures(sim, rst)
    reads = [r["read_after_s"] for r in replugs]
    summaries = rst.devices()
    devices: dict[str, Any] = {d: {"states": rst.states(d), **summaries.get(d, {})}
                               for d in (*sim.devices, *summaries)}
    final = rst.final or {}
    hist = (final.get("control") or {}).get("period_jitter_hist")
    if hist:  # measured inside the runtime (its control loop)
        timing.update(hist_figures(hist))
    return {
        "stop": stop,
        "sim_seconds": sim_seconds,
        "wall_seconds": t_end - t_start,
        "log": sim.log,
        "auv_log": sim.auv_log,
        "auv": sim.acoustics.auv if sim.acoustics is not None else None,
        "faults": failsafe_entries(rst),
        "devices": devices,
        "sim_thruster_controller": dict(sim.counters),
        "hil": {
            "runtime": {
                "command": cmd, "pid": proc.pid, "exit_code": proc.returncode,
                "exited_before_the_end": early_exit, "startup_s": round(startup_s, 3),
                "log": str(run_dir / "runtime.log"), "errors": errlog.errors[:20],
                "status_file": str(status_file), "status_snapshots": rst.snapshots,
                "status_final": rst.final is not None, "status_bad_lines": rst.bad_lines,
                "counters": final.get("counters", {}),
                "components": {c: {"state": v.get("state"), "restarts": v.get("restarts"),
                                   "failures": v.get("failures")}
                               for c, v in (final.get("components") or {}).items()},
            },
            "zero_thrust_on_exit": bool(after) and after[-1][1:] == (0.0, 0.0),
            "last_command": list(last) if last else None,
            "links": sim.links,
            "injected": [f.label for f in faults],
            "events": [e.as_dict() for e in sim.events],
            "modes": rst.modes,
            "mission": final.get("mission"),
            "follow_steering_s": round(w - wall0, 3)
            if (w := rst.steering_since("follow")) is not None else None,
            "health": [tr.as_dict(wall0) for tr in rst.transitions],
            "failsafes": [{"t": round(e.wall - wall0, 3), "message": e.text}
                          for e in rst.of_kind("failsafe")],
            "runtime_events": [e.as_dict(wall0) for e in rst.events],
            "replugs": replugs,
            "replug_max_s": max((r for r in reads if r is not None), default=None)
            if all(r is not None for r in reads) else None,
            "timing": timing,
            "cpu_percent": cpu,
            "rss_start_mb": round(rss0, 2) if rss0 is not None else None,
            "rss_end_mb": round(rss1, 2) if rss1 is not None else None,
            "rss_max_mb": round(max(s[2] for s in samples), 2) if samples else None,
            "ports": {d: dict(p.counters) for d, p in sim.ports.items()},
        },
    }


def run_hil(scn: Scenario, faults: list[FaultSpec], run_dir: str | Path | None = None,
            duration_s: float | None = None, quiet: bool = True) -> HilResult:
    """Run a scenario in HIL, in real time; returns the report (like ``zarco sim``'s)."""
    rd = Path(run_dir) if run_dir else Path(tempfile.mkdtemp(prefix="zarco-hil-"))
    rd.mkdir(parents=True, exist_ok=True)
    rd = rd.resolve()  # the device links are serial paths: absolute
    # the receiver's clock says now (the runtime compares nothing with it but
    # epochs; this keeps a HIL capture plausible)
    scn.world.start_utc = datetime.now(UTC).isoformat(timespec="seconds")
    o = scn.runtime.origin
    legs = build_legs(scn.mission, LocalFrame(o.lat_deg, o.lon_deg, o.alt_m))
    limit = scn.scenario.max_duration_s
    if duration_s:
        limit = min(limit, duration_s)
    w0 = time.perf_counter()
    raw = asyncio.run(_run(scn, faults, legs, rd, limit, quiet))
    log: TrackLog = raw.pop("log")
    auv_log = raw.pop("auv_log")
    auv = raw.pop("auv")
    hil = raw.pop("hil")
    if auv is not None:  # following the AUV: distances on the truth
        figures = follow_figures(log, auv_log, auv)
    else:
        figures = line_figures(log, legs)
        clean = clean_legs(log, faults)
        hil["legs_without_faults"] = clean
        hil["xtrack_rms_without_faults_m"] = pooled_rms(figures["legs"], clean)
    hil["wall_total_s"] = round(time.perf_counter() - w0, 3)
    sat = sum(1 for u1, u2 in zip(log.u1, log.u2, strict=True)
              if max(abs(u1), abs(u2)) >= 99.95)
    report: dict[str, Any] = {
        "scenario": scn.scenario.name,
        "seed": scn.scenario.seed,
        "stop": raw["stop"],
        "sim_seconds": round(raw["sim_seconds"], 3),
        "wall_seconds": round(raw["wall_seconds"], 3),
        "speedup": round(raw["sim_seconds"] / raw["wall_seconds"], 3)
        if raw["wall_seconds"] > 0 else None,
        **figures,
        # the runtime's saturation flag is in its process: here, the share of
        # true-track samples whose last command on the wire was at ±100
        "saturation_fraction": sat / len(log.t) if log.t else 0.0,
        "command_step_rms": command_step_rms(log),
        "faults": raw["faults"],
        "devices": raw["devices"],
        "sim_thruster_controller": raw["sim_thruster_controller"],
        "hil": hil,
    }
    return HilResult(scn, legs, log, report, rd, auv_log)


def follow_summary(report: dict[str, Any]) -> str:
    """The headline figures of a follow run (distances on the truth)."""

    def m(v: Any) -> str:
        return "-" if v is None else f"{v:.2f} m"

    lines = [
        f"scenario {report['scenario']}  seed {report['seed']}  ({report['stop']})",
        f"ran {report['sim_seconds']:.1f} s in {report['wall_seconds']:.2f} s wall",
        f"ASV–AUV distance (truth): at the start {m(report['distance_start_m'])}, when the "
        f"AUV starts moving ({report['auv_moves_s']:g} s) {m(report['distance_hover_end_m'])}",
        f"  first leg (from {report['auv_moves_s'] + LEG_SETTLE_S:g} s): median "
        f"{m(report['distance_leg_median_m'])}  p95 {m(report['distance_leg_p95_m'])}  max "
        f"{m(report['distance_leg_max_m'])}",
    ]
    for tr in report["turns"]:
        lines.append(f"  after the turn at {tr['t_s']:.1f} s: max {m(tr['distance_max_m'])}, "
                     f"last {FINAL_S:g} s median {m(tr['distance_final_median_m'])}")
    lines.append(f"  last {FINAL_S:g} s: median {m(report['distance_final_median_m'])}; "
                 f"max over the run {m(report['distance_max_m'])}; the AUV went "
                 f"{report['auv_travel_m']:.1f} m, the ASV {report['asv_travel_m']:.1f} m")
    if report.get("faults"):
        lines.append("failsafes: " + "; ".join(report["faults"]))
    return "\n".join(lines)


def summary(report: dict[str, Any]) -> str:
    from zarco_tools.cli import summary as sim_summary

    h = report["hil"]
    t = h["timing"]
    rt = h["runtime"]

    def f(v: Any, unit: str = "") -> str:
        return "-" if v is None else f"{v:.4g}{unit}"

    head = sim_summary(report) if "xtrack_rms_m" in report else follow_summary(report)
    lines = [
        head, "",
        f"runtime: started in {rt['startup_s']:.2f} s, exit code {rt['exit_code']}"
        f"{' (EXITED BEFORE THE END)' if rt['exited_before_the_end'] else ''}, zero thrust "
        f"on exit: {'yes' if h['zero_thrust_on_exit'] else 'NO'}; CPU {f(h['cpu_percent'], ' %')}"
        f", RSS {f(h['rss_start_mb'], ' MB')} → {f(h['rss_end_mb'], ' MB')}",
        f"timing at the ports: control period jitter p99 {f(t['jitter_p99_ms'], ' ms')} "
        f"(max {f(t['jitter_max_ms'], ' ms')}; inside the runtime: p99 "
        f"{f(t.get('runtime_jitter_p99_ms'), ' ms')}); GPS → command latency p50 "
        f"{f(t['latency_p50_ms'], ' ms')}, p99 {f(t['latency_p99_ms'], ' ms')}",
        f"modes: {' → '.join(h['modes'])}",
    ]
    if "legs_without_faults" in h:
        lines.append(f"legs without faults {h['legs_without_faults']}: cross-track RMS "
                     f"{f(h['xtrack_rms_without_faults_m'], ' m')}")
    if h["injected"]:
        lines.append("injected: " + "; ".join(h["injected"]))
    for r in h["replugs"]:
        lines.append(f"replug {r['device']} at {r['t']:.1f} s: opened again after "
                     f"{f(r['opened_after_s'], ' s')}, read again after "
                     f"{f(r['read_after_s'], ' s')}")
    for d, info in report["devices"].items():
        lines.append(f"{d}: " + " → ".join(info.get("states", [])))
    return "\n".join(lines)


def main_hil(args: Any) -> int:
    from hil.scenario import load_hil_scenario
    from zarco_tools.run_outputs import RunOutputs

    scn, faults = load_hil_scenario(args.scenario, args.set, args.seed)
    if args.no_faults:
        faults = []
    out = RunOutputs.check(args.report, args.plot)  # before the run
    run_dir = writable_dir(args.run_dir, "--run-dir", create=True) if args.run_dir else None
    try:
        res = run_hil(scn, faults, run_dir, args.duration, quiet=args.quiet)
    except HilError as exc:
        print(f"zarco hil: {exc}", file=sys.stderr)
        return 1
    out.write_report(res.report)

    def draw(path: Path) -> None:
        from zarco_tools.plot import plot_follow, plot_lines

        title = f"{scn.scenario.name} (HIL): seed {scn.scenario.seed}, "
        if "xtrack_rms_m" not in res.report:
            # the tracker's fixes and track are in the runtime's process: truth only
            dmax = res.report.get("distance_max_m")
            plot_follow(path, res.log, {"auv_log": res.auv_log, "auv_msgs": []},
                        title + ("distance max -" if dmax is None
                                 else f"distance max {dmax:.2f} m"))
        else:
            rms = res.report.get("xtrack_rms_m")
            plot_lines(path, res.log, res.legs,
                       title + ("RMS -" if rms is None else f"RMS {rms:.3f} m"))

    out.write_plot(draw)
    print(summary(res.report))
    print(f"\nrun directory: {res.run_dir}")
    if out.written:
        print("\n".join(out.written))
    for line in out.failed:
        print(f"zarco hil: {line}", file=sys.stderr)
    rt = res.report["hil"]["runtime"]
    return 1 if rt["exited_before_the_end"] or rt["exit_code"] != 0 or out.failed else 0
