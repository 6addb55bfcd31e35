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
        self._devices: dict[str, MemoryTransport] = {}
        self._unplugged: set[str] = set()

    def create(self, name: str) -> MemoryTransport:
        """Create the link ``name``; returns the *device* end."""
        dev, rt = memory_link(name)
        self._ports[name] = rt
        self._devices[name] = dev
        return dev

    def device_end(self, name: str) -> MemoryTransport:
        """The device end of link ``name`` as it is now (a replug makes a new one)."""
        return self._devices[name]

    def plugged(self, name: str) -> bool:
        return name not in self._unplugged

    def unplug(self, name: str) -> None:
        """The device goes away: both ends close, opening it fails until :meth:`replug`."""
        if name in self._ports and name not in self._unplugged:
            self._unplugged.add(name)
            self._devices[name]._rx.close()
            self._devices[name]._tx.close()

    def replug(self, name: str) -> MemoryTransport:
        """The device comes back at the same URL (a fresh link); returns its device end."""
        self._unplugged.discard(name)
        listener = self._devices[name]._rx.listener if name in self._devices else None
        dev = self.create(name)
        if listener is not None:
            dev.on_receive(listener)
        return dev

    def runtime_end(self, name: str) -> MemoryTransport:
        if name in self._unplugged:
            raise TransportError(f"sim://{name}: no such device (unplugged)")
        try:
            return self._ports[name]
        except KeyError:
            raise TransportError(f"sim://{name}: no such simulated port") from None

    async def open(self, url: str, baudrate: int) -> Transport:
        if not url.startswith("sim://"):
            raise TransportError(f"{url or '(empty)'}: the simulator opens only sim:// ports")
        name = url[len("sim://"):]
        rt = self.runtime_end(name)
        if rt._rx.closed or rt._tx.closed:  # reopened after a close: a fresh link
            self.replug(name)
            rt = self._ports[name]
        return rt
