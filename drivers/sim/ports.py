"""The simulated backend's ports: ``sim://NAME`` in-memory links.

Injected into the runtime in place of the vessel's serial ports
(:class:`drivers.transports.SystemPorts`); the simulated devices write at the
device end, the runtime's drivers open the other end by URL.
"""

from __future__ import annotations

from drivers.transports import MemoryTransport, Transport, TransportError, memory_link


class SimPorts:
    """Registry of the simulated backend's ports, by name (``sim://NAME``)."""

    schemes: tuple[str, ...] = ("sim",)

    def __init__(self) -> None:
        self._ports: dict[str, MemoryTransport] = {}

    def create(self, name: str) -> MemoryTransport:
        """Create the link ``name``; returns the *device* end."""
        dev, rt = memory_link(name)
        self._ports[name] = rt
        return dev

    def runtime_end(self, name: str) -> MemoryTransport:
        try:
            return self._ports[name]
        except KeyError:
            raise TransportError(f"sim://{name}: no such simulated port") from None

    async def open(self, url: str, baudrate: int) -> Transport:
        if not url.startswith("sim://"):
            raise TransportError(f"{url or '(empty)'}: the simulator opens only sim:// ports")
        return self.runtime_end(url[len("sim://"):])
