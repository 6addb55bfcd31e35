"""Settings of one device driver (the ``[devices.*]`` tables of the runtime's
configuration): where the device is and how to judge its health."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec


@dataclass(slots=True)
class Device:
    """One device: where it is (a URL, as pyserial names ports) and how to judge it.

    ``url`` forms: ``/dev/ttyUSB0`` or ``serial:///dev/ttyUSB0``
    (serial port at ``baudrate``), ``tcp://host:port``, ``sim://NAME`` (the
    simulated backend's in-memory port), ``loop://`` (pyserial loopback).
    """

    url: str = spec("", "", "device address")
    baudrate: int = spec(115200, "bit/s", "serial speed", min=1200, max=4_000_000)
    enabled: bool = spec(True, "", "read this device")
    stale_s: float = spec(1.0, "s", "no valid sentence for this long → stale", min=0.05, max=60.0)
    corrections_url: str = spec("", "", "RTCM3 corrections written to this device's port, "
                                "from a serial port, tcp://HOST:PORT or file://PATH "
                                "(empty: none); only whole frames with a valid CRC-24Q pass")
    corrections_rate_bps: float = spec(4000.0, "B/s", "pace of a file:// corrections "
                                       "source", min=1.0, max=1e7)
    reopen_s: float = spec(3.0, "s", "no bytes at all for this long → close and reopen the "
                           "port (0: never)", min=0.0, max=600.0)
    variation_deg: float | None = spec(
        None, "deg", "magnetic variation (east +) when the sentences carry none",
        min=-90.0, max=90.0,
    )
