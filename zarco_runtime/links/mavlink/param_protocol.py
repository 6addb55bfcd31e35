"""The MAVLink parameter protocol: PARAM_REQUEST_LIST, PARAM_REQUEST_READ and
PARAM_SET answered with PARAM_VALUE, over the supervisor's parameters
(:mod:`.params` names them).

A PARAM_SET is the supervisor's ``param`` command: validated, acknowledged,
published and recorded by the supervisor, never written here.  Taken, the
new value as the supervisor applied it goes to every connected ground station
(from its :class:`~zarco_core.messages.ParamChange`, so a change from the
shore link or ``zarco ctl`` is seen as well); refused, the ground station
that asked gets the unchanged value back and a STATUSTEXT with the reason."""

from __future__ import annotations

import logging
from typing import Any

from zarco_core.messages import ParamChange
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.params import Param, ParamTable
from zarco_runtime.links.mavlink.protocol import mav

log = logging.getLogger("zarco.mavlink")


class ParamProtocol:
    """PARAM_* requests (see the module docstring)."""

    def __init__(self, core: Core) -> None:
        self.core = core
        self.table = ParamTable(core.cfg)

    def send_value(self, link: Link, p: Param, value: Any = None) -> None:
        """PARAM_VALUE of ``p``: ``value`` (as the registry types it), or the
        current one."""
        link.send(mav.MAVLink_param_value_message(p.name.encode(), self.table.wire(p, value),
                                                  p.ptype, len(self.table), p.index))

    def on_list(self, link: Link, m: Any) -> None:
        if not self.core.for_us(m):
            return
        for p in self.table.params:
            self.send_value(link, p)

    def on_read(self, link: Link, m: Any) -> None:
        if not self.core.for_us(m):
            return
        p = self.table.find(str(m.param_id), int(m.param_index))
        if p is not None:
            self.send_value(link, p)

    def on_set(self, link: Link, m: Any) -> None:
        c = self.core
        if not c.for_us(m):
            return
        src = m.get_srcSystem()
        name = str(m.param_id)
        p = self.table.find(name, -1)
        if p is None:
            c.event("param", f"parameter {name[:16]} from mavlink:{src} refused: no such "
                    "parameter")
            return
        c.spawn(self._set(link, src, p, float(m.param_value)))

    async def _set(self, link: Link, src: int, p: Param, x: float) -> None:
        c = self.core
        try:
            try:
                value = self.table.from_wire(p, x)
            except ValueError as exc:  # not a value of its type: never reaches the supervisor
                c.event("param", f"parameter from mavlink:{src} refused: {exc}")
                ack = None
            else:
                ack = await c.supervise("param", {"name": p.key, "value": value}, src)
        except Exception:  # ours, not the ground station's: answered, never a restart
            c.counters.handler_errors += 1
            log.exception("mavlink: parameter %s from %d", p.name, src)
            ack = None
        if ack is not None and ack.ok:
            c.counters.params_set += 1  # the new value goes out with its ParamChange
            return
        c.counters.params_refused += 1
        if ack is not None:
            c.tell_refusal(link, ack)
        self.send_value(link, p)  # unchanged, after the reason

    def on_change(self, ch: ParamChange) -> None:
        """A parameter changed (whoever asked): every ground station hears it."""
        p = self.table.by_key.get(ch.name)
        if p is None:
            return
        for ln in self.core.links:
            self.send_value(ln, p, ch.value)

    def refuse_unsigned(self, link: Link, m: Any) -> None:
        """An unsigned PARAM_SET (addressed to the boat): the unchanged value back."""
        p = self.table.find(str(m.param_id), -1)
        if p is not None:
            self.send_value(link, p)
