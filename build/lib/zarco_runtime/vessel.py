"""``zarco run``: the runtime on the vessel computer.

Order of start: read and validate the configuration (refused with the file,
the key and the reason: exit 2), check it can run here (device URLs,
missions that need a disabled device: exit 2), take the device locks (a
second runtime on the same devices is refused: exit 2), then start every
component.  SIGTERM, SIGINT, SIGHUP and SIGQUIT all stop it the same way:
every component is cancelled and the thruster driver writes zero thrust as
the last command (exit 0).  A process killed outright (SIGKILL) cannot do
that: the thruster controller's own timeout (no valid ``$PZTHR`` for 0.5 s →
zero thrust) stops the boat.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import logging
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from zarco_core.config import ConfigError, load_toml
from zarco_core.messages import Event, VesselStatus
from zarco_runtime import sd_notify
from zarco_runtime.config_file import boot_mission, check_runtime, load_runtime_config
from zarco_runtime.instance_lock import InstanceLock, LockedError
from zarco_runtime.runtime import Runtime

log = logging.getLogger("zarco")
#: signals that stop the runtime (all of them leave zero thrust)
STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT)


class StatusFile:
    """``--status FILE``: the status snapshot (``"kind": "status"``, 1 Hz) and every
    event (``"kind": "event"``, its own kind under ``"event"``) as JSON lines, and
    a ``"final": true`` line on exit with the control loop's period-jitter
    histogram."""

    def __init__(self, path: str, runtime: Runtime) -> None:
        self.runtime = runtime
        self.fh: IO[str] = Path(path).open("a", buffering=1)  # noqa: SIM115 (close())
        runtime.bus.listen(VesselStatus, self._status)
        runtime.bus.listen(Event, self._event)
        self.last: VesselStatus | None = None

    def _write(self, d: dict[str, Any]) -> None:
        d["wall"] = round(time.time(), 3)
        self.fh.write(json.dumps(d) + "\n")

    def _status(self, st: VesselStatus) -> None:
        self.last = st
        self._write({"kind": "status", **dataclasses.asdict(st)})

    def _event(self, ev: Event) -> None:
        self._write({"kind": "event", "event": ev.kind, "t": ev.t, "text": ev.text,
                     "source": ev.source})

    def close(self) -> None:
        ctl = self.runtime.live.control
        sup = self.runtime.live.supervisor
        st = sup.snapshot(sup.clock.now()) if sup is not None else self.last
        d: dict[str, Any] = {"kind": "status", "final": True,
                             **(dataclasses.asdict(st) if st is not None else {})}
        if ctl is not None:
            d["control"] = {"ticks": ctl.ticks, "faults": ctl.faults,
                            "saturated_ticks": ctl.saturated_ticks,
                            "period_jitter_hist": ctl.period_jitter_hist}
        self._write(d)
        self.fh.close()


def _sets(config: str, overrides: list[str], table: str, key: str) -> bool:
    """Whether the file or an override sets ``[table] key``."""
    raw = load_toml(config).get(table)
    if isinstance(raw, dict) and key in raw:
        return True
    return any(o.split("=", 1)[0].strip() == f"{table}.{key}" for o in overrides)


def device_urls(runtime: Runtime) -> dict[str, str]:
    return {f"devices.{n}.url": d.url for n, d in runtime.cfg.devices.items() if d.enabled}


def run_vessel(config: str, overrides: list[str], status: str | None = None,
               hooks: list[Callable[[Runtime], None]] | None = None) -> int:
    """``zarco run``; returns the exit code (2: refused before starting)."""
    cfg, mission = load_runtime_config(config, overrides)
    file = config if not overrides else f"{config} (with --set)"
    check_runtime(cfg, mission, file)
    if not _sets(config, overrides, "record", "enabled"):
        cfg.record.enabled = True  # the vessel records unless told not to
    boot = boot_mission(cfg, mission, Path(config).stem)
    runtime = Runtime(cfg, boot=boot, notify=sd_notify.from_environment(),
                      config_dir=str(Path(config).resolve().parent))
    for hook in hooks or []:
        hook(runtime)
    lock = InstanceLock(device_urls(runtime))
    try:
        lock.acquire()
    except LockedError as exc:
        raise ConfigError(file, exc.key, str(exc).split(": ", 1)[1]) from None
    status_file = StatusFile(status, runtime) if status else None
    stopped: list[str] = []

    async def main() -> None:
        task = asyncio.current_task()
        loop = asyncio.get_running_loop()
        assert task is not None

        def stop(sig: signal.Signals) -> None:
            if not stopped:
                stopped.append(sig.name)
                log.warning("stopping: %s", sig.name)
                task.cancel()

        for sig in STOP_SIGNALS:
            loop.add_signal_handler(sig, stop, sig)
        try:
            await runtime.run()
        except asyncio.CancelledError:
            if not stopped:
                raise
        finally:
            if status_file is not None:
                status_file.close()

    try:
        asyncio.run(main())
    finally:
        lock.release()
    log.warning("stopped (%s); zero thrust sent", stopped[0] if stopped else "exit")
    return 0
