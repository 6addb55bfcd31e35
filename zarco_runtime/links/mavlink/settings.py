"""Settings of the MAVLink endpoint (``[mavlink]``)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from zarco_core.config import spec

#: what the GCS may stream, with the default rate (Hz) of each (0: only on request)
STREAMS: dict[str, float] = {
    "HEARTBEAT": 1.0,
    "SYS_STATUS": 1.0,
    "GPS_RAW_INT": 2.0,
    "GLOBAL_POSITION_INT": 5.0,
    "ATTITUDE": 10.0,
    "VFR_HUD": 4.0,
    "SERVO_OUTPUT_RAW": 2.0,
    "MISSION_CURRENT": 1.0,
    "HOME_POSITION": 0.0,
}
#: the fastest stream rate a GCS may ask (Hz)
MAX_RATE_HZ = 50.0

_NET = re.compile(r"^(udpin|udpout|udpbcast|tcp|tcpin):([^:]+):(\d{1,5})$")
KEY_BYTES = 32


def read_signing_key(path: str) -> bytes:
    """The 32-byte MAVLink 2 signing secret in ``path``: 32 raw bytes, or 64 hex
    digits (whitespace around them ignored).  Raises ValueError saying why not."""
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise ValueError(f"cannot read {path}: {exc.strerror or exc}") from None
    if len(raw) == KEY_BYTES:
        return raw
    text = raw.strip()
    if len(text) == 2 * KEY_BYTES:
        try:
            return bytes.fromhex(text.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            pass
    raise ValueError(f"{path} must hold the 32-byte secret: 32 raw bytes or 64 hex digits "
                     f"(has {len(raw)} bytes)")


def check_url(url: str) -> str:
    """Why ``url`` is not a MAVLink connection this endpoint opens ("" when it is):
    ``udpin:HOST:PORT``, ``udpout:HOST:PORT``, ``udpbcast:HOST:PORT``,
    ``tcp:HOST:PORT`` (connect), ``tcpin:HOST:PORT`` (listen), or a serial device
    path with an optional ``,BAUD``."""
    m = _NET.match(url)
    if m:
        port = int(m.group(3))
        if not 0 < port < 65536:
            return f"port {port} out of range"
        return ""
    if url.startswith("/") or re.match(r"^COM\d+", url):
        dev, _, baud = url.partition(",")
        if baud and not baud.isdigit():
            return f"baud rate {baud!r} is not a number"
        if ":" in dev:
            return "a serial device path cannot contain ':'"
        return ""
    return ("expected udpin:HOST:PORT, udpout:HOST:PORT, udpbcast:HOST:PORT, tcp:HOST:PORT, "
            "tcpin:HOST:PORT or a serial device (/dev/ttyUSB0,57600)")


@dataclass(slots=True)
class MavlinkSettings:
    """The MAVLink endpoint: the boat as a ground station sees it (QGroundControl,
    MAVProxy).  Each ``url`` is a pymavlink connection string and gets its own
    connection, with its own stream rates."""

    enabled: bool = spec(False, "", "run the MAVLink endpoint")
    url: object = spec("udpout:127.0.0.1:14550", "", "pymavlink connection string, or a list "
                       "of them: udpout:HOST:14550 (to a GCS listening, QGroundControl's "
                       "default), udpin:0.0.0.0:14550, tcpin:0.0.0.0:5760, tcp:HOST:PORT, "
                       "a serial device /dev/ttyUSB0,57600")
    signing_key_file: str = spec("", "", "file with the 32-byte MAVLink 2 signing secret "
                                 "(32 raw bytes or 64 hex digits); with it, every message "
                                 "that is not signed with it is refused (empty: no signing)")
    system_id: int = spec(1, "", "the boat's MAVLink system id", min=1, max=255)
    component_id: int = spec(1, "", "the boat's MAVLink component id (1: autopilot)",
                             min=1, max=255)
    rates_hz: dict[str, float] = spec(dict, "Hz", "default stream rates by message name "
                                      "(0: only on request); unset ones keep their defaults: "
                                      + ", ".join(f"{k} {v:g}" for k, v in STREAMS.items()),
                                      min=0.0, max=MAX_RATE_HZ)
    auv_system_id: int = spec(0, "", "the MAVLink system id of the tracked AUV, which the "
                              "endpoint also speaks for (0: the boat's system_id + 1)",
                              min=0, max=255)
    mission_speed_mps: float = spec(1.0, "m/s", "speed of an uploaded mission that has no "
                                    "DO_CHANGE_SPEED item", min=0.05, max=3.0)

    def auv_sysid(self) -> int:
        """The AUV's system id (``auv_system_id``, or the boat's + 1)."""
        return self.auv_system_id or self.system_id + 1

    def urls(self) -> list[str]:
        """The connection strings (``url`` as a list)."""
        u = self.url
        if isinstance(u, str):
            return [u]
        return [str(x) for x in u] if isinstance(u, list) else []

    def validate(self) -> None:
        u = self.url
        if isinstance(u, str):
            urls = [u]
        elif isinstance(u, list) and u and all(isinstance(x, str) for x in u):
            urls = u
        else:
            raise ValueError(f"url: expected a connection string or a non-empty list of them, "
                             f"got {u!r}")
        for i, x in enumerate(urls):
            why = check_url(x)
            if why:
                raise ValueError(f"url: {x!r}{f' (entry {i})' if len(urls) > 1 else ''}: {why}")
        if len(set(urls)) != len(urls):
            raise ValueError("url: the same connection is listed twice")
        for name, hz in self.rates_hz.items():
            if name not in STREAMS:
                raise ValueError(f"rates_hz: {name!r} is not a stream (one of "
                                 f"{', '.join(STREAMS)})")
            if not 0.0 <= hz <= MAX_RATE_HZ:
                raise ValueError(f"rates_hz: {name} must be within 0..{MAX_RATE_HZ:g} Hz, "
                                 f"got {hz:g}")
        auv = self.auv_sysid()
        if self.enabled and not 1 <= auv <= 255:
            raise ValueError(f"auv_system_id: the boat is system {self.system_id}, so the "
                             "AUV cannot be the next one: set auv_system_id (1..255)")
        if auv == self.system_id:
            raise ValueError(f"auv_system_id: {auv} is the boat's system_id")
        if self.rates_hz.get("HEARTBEAT", 1.0) != 1.0:
            raise ValueError("rates_hz: HEARTBEAT is sent at 1 Hz")
        if self.signing_key_file:
            try:
                read_signing_key(self.signing_key_file)
            except ValueError as exc:
                raise ValueError(f"signing_key_file: {exc}") from None
