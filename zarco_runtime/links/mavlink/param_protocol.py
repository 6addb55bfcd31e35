"""The MAVLink parameter protocol: PARAM_REQUEST_LIST, PARAM_REQUEST_READ and
PARAM_SET answered with PARAM_VALUE, over the table of :mod:`.params`.

A write that is refused gets the unchanged value back and a STATUSTEXT with
the reason; a write taken is sent to every connected ground station."""

from __future__ import annotations

from typing import Any

from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.params import Param, ParamTable
from zarco_runtime.links.mavlink.protocol import mav


class ParamProtocol:
    """PARAM_* requests (see the module docstring)."""

    def __init__(self, core: Core) -> None:
        self.core = core
        self.table = ParamTable(core.cfg)

    def send_value(self, link: Link, p: Param) -> None:
        link.send(mav.MAVLink_param_value_message(p.name.encode(), self.table.value(p),
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
            c.event("param", f"parameter {name} from mavlink:{src} refused: no such "
                    "parameter")
            return
        why, old, new = self.table.set(p, float(m.param_value))
        if why:
            c.counters.params_refused += 1
            c.event("param", f"parameter from mavlink:{src} refused: {why}")
            self.send_value(link, p)
            return
        c.counters.params_set += 1
        c.event("param", f"{p.name} ({p.section}.{p.field}) = {new} (was {old}) by "
                f"mavlink:{src}")
        for ln in c.links:  # every GCS sees the new value
            self.send_value(ln, p)

    def refuse_unsigned(self, link: Link, m: Any) -> None:
        """An unsigned PARAM_SET (addressed to the boat): the unchanged value back."""
        p = self.table.find(str(m.param_id), -1)
        if p is not None:
            self.send_value(link, p)
