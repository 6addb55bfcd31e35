"""Mission transfer: the MAVLink mission protocol on the boat's side.

Upload (MISSION_COUNT, then MISSION_REQUEST_INT / MISSION_ITEM_INT item by
item, re-requested after :data:`UPLOAD_RETRY_S`, given up after
:data:`UPLOAD_RETRIES`): the items become a supervisor ``mission`` command
with ``start = false`` (:mod:`.mission`), and the MISSION_ACK carries its
verdict.  One upload at a time; another ground station's is refused while one
is in progress.  Download (MISSION_REQUEST_LIST, MISSION_REQUEST_INT): the
supervisor's loaded mission (its status's waypoints; with the speed item of
the upload that gave them, if one did).  Progress: MISSION_CURRENT at every change and
MISSION_ITEM_REACHED as each waypoint is passed, from the supervisor's
directives and the guidance's status."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from zarco_core.messages import GuidanceStatus, Mode, VesselStatus
from zarco_runtime.guidance.directive import Directive
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.link import Link
from zarco_runtime.links.mavlink.mission import (
    MAX_ITEMS,
    Item,
    items_from_mission,
    items_from_points,
    parse_items,
)
from zarco_runtime.links.mavlink.protocol import mav

log = logging.getLogger("zarco.mavlink")

#: mission upload: re-request an item after this long, this many times (s, count)
UPLOAD_RETRY_S = 1.0
UPLOAD_RETRIES = 5


@dataclass(slots=True)
class Upload:
    """A mission upload in progress, from one GCS on one link."""

    link: Link
    sysid: int
    compid: int
    count: int
    items: list[Item | None]
    next: int = 0
    t_last: float = 0.0
    retries: int = 0
    done: bool = False


class MissionTransfer:
    """Upload, download and progress of the mission (see the module docstring)."""

    def __init__(self, core: Core) -> None:
        self.core = core
        # the mission as a GCS sees it
        self.items: list[Item] = []
        self.wp_seqs: list[int] = []
        self.wps: tuple[tuple[float, float], ...] = ()
        self.mission_state = mav.MISSION_STATE_NO_MISSION
        self.cur = 0  # the waypoint (index into wps) the boat is heading for
        self.upload: Upload | None = None
        #: the supervisor's mission these items are for (VesselStatus.mission_id)
        self.mission_id = -1
        #: the items of the last upload taken, and its waypoints: served while the
        #: supervisor's loaded mission has these waypoints (they carry its speed)
        self.uploaded: tuple[tuple[tuple[float, float], ...], list[Item], list[int]] | None = None

    # ---------------------------------------------------------------- upload

    def poll(self, now: float) -> None:
        """Re-request a missing item, or give the upload up."""
        up = self.upload
        if up is None or up.done or now - up.t_last <= UPLOAD_RETRY_S:
            return
        if up.retries >= UPLOAD_RETRIES:
            self.upload = None
            self.core.mission_ack(up.link, up.sysid, up.compid,
                                  mav.MAV_MISSION_OPERATION_CANCELLED)
            self.core.event("mission", f"mission upload from mavlink:{up.sysid} timed out at "
                            f"item {up.next} of {up.count}")
        else:
            up.retries += 1
            self._request_item(up, now)

    def on_count(self, link: Link, m: Any) -> None:
        c = self.core
        if not c.for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        mtype = int(getattr(m, "mission_type", 0))
        count = int(m.count)
        if mtype != mav.MAV_MISSION_TYPE_MISSION:
            c.mission_ack(link, src, comp, mav.MAV_MISSION_ACCEPTED if count == 0
                          else mav.MAV_MISSION_UNSUPPORTED, mtype)
            return
        up = self.upload
        if up is not None and not up.done and (up.link, up.sysid) != (link, src):
            c.mission_ack(link, src, comp, mav.MAV_MISSION_DENIED)
            c.event("mission", f"mission upload from mavlink:{src} refused: another "
                    f"upload (mavlink:{up.sysid}) is in progress")
            return
        if count == 0:  # an empty mission: the loaded one is cleared
            self.upload = None
            c.spawn(self._clear(link, src, comp, mtype))
            return
        if count > MAX_ITEMS:
            c.mission_ack(link, src, comp, mav.MAV_MISSION_NO_SPACE)
            return
        self.upload = up = Upload(link, src, comp, count, [None] * count)
        self._request_item(up, c.clock.now())

    def _request_item(self, up: Upload, now: float) -> None:
        up.t_last = now
        up.link.send(mav.MAVLink_mission_request_int_message(up.sysid, up.compid, up.next,
                                                             mav.MAV_MISSION_TYPE_MISSION))

    def on_item(self, link: Link, m: Any, is_int: bool) -> None:
        if not self.core.for_us(m):
            return
        up = self.upload
        src = m.get_srcSystem()
        if up is None or up.done or (up.link, up.sysid) != (link, src):
            return
        if int(getattr(m, "mission_type", 0)) != mav.MAV_MISSION_TYPE_MISSION:
            return
        seq = int(m.seq)
        now = self.core.clock.now()
        if seq != up.next:
            if seq > up.next:  # one went missing: ask again for the one we need
                self._request_item(up, now)
            return  # a repeat of one we have
        up.items[seq] = Item.from_msg(m, is_int)
        up.next += 1
        up.retries = 0
        if up.next < up.count:
            self._request_item(up, now)
            return
        up.done = True
        self.core.spawn(self._finish_upload(up))

    async def _finish_upload(self, up: Upload) -> None:
        try:
            await self._take_upload(up)
        except Exception:  # ours, not the ground station's: answered, never a restart
            self.core.counters.handler_errors += 1
            log.exception("mavlink: mission upload from %d", up.sysid)
            self.core.mission_ack(up.link, up.sysid, up.compid, mav.MAV_MISSION_ERROR)
        finally:
            if self.upload is up:
                self.upload = None

    async def _take_upload(self, up: Upload) -> None:
        c = self.core
        items = [it for it in up.items if it is not None]
        parsed = parse_items(items, c.s.mission_speed_mps)
        source = f"mavlink:{up.sysid}"
        if parsed.result != mav.MAV_MISSION_ACCEPTED:
            c.counters.missions_refused += 1
            c.event("mission", f"mission upload from {source} refused: {parsed.reason}")
            c.mission_ack(up.link, up.sysid, up.compid, parsed.result)
        else:
            ack = await c.supervise("mission", {
                "waypoints": [[lat, lon] for lat, lon in parsed.waypoints],
                "speed_mps": parsed.speed_mps, "start": False,
                "name": f"{len(parsed.waypoints)} waypoints from {source}"}, up.sysid)
            if ack is not None and ack.ok:
                c.counters.missions_uploaded += 1
                self.uploaded = (tuple(parsed.waypoints), items, parsed.wp_seqs)
                self.items = items
                self.wp_seqs = parsed.wp_seqs
                self.wps = tuple(parsed.waypoints)
                self.cur = 0
                self.mission_state = mav.MISSION_STATE_NOT_STARTED
                c.mission_ack(up.link, up.sysid, up.compid, mav.MAV_MISSION_ACCEPTED)
                self.broadcast_current()
            else:
                c.counters.missions_refused += 1
                if ack is not None:
                    c.tell_refusal(up.link, ack)
                c.mission_ack(up.link, up.sysid, up.compid,
                              mav.MAV_MISSION_ERROR if ack is not None and ack.mode == "unknown"
                              else mav.MAV_MISSION_INVALID)

    async def _clear(self, link: Link, src: int, comp: int, mtype: int) -> None:
        """The supervisor's ``mission {"clear": true}``: its loaded mission is
        forgotten (refused while it runs); MISSION_ACK ACCEPTED, or ERROR with the
        supervisor's reason as a status text."""
        c = self.core
        try:
            ack = await c.supervise("mission", {"clear": True}, src)
        except Exception:  # ours, not the ground station's: answered, never a restart
            c.counters.handler_errors += 1
            log.exception("mavlink: mission clear from %d", src)
            ack = None
        if ack is None or not ack.ok:
            if ack is not None:
                c.tell_refusal(link, ack)
            c.mission_ack(link, src, comp, mav.MAV_MISSION_ERROR, mtype)
            return
        self.items, self.wp_seqs, self.wps = [], [], ()
        self.cur = 0
        self.mission_state = mav.MISSION_STATE_NO_MISSION
        c.mission_ack(link, src, comp, mav.MAV_MISSION_ACCEPTED, mtype)
        self.broadcast_current()

    def on_clear(self, link: Link, m: Any) -> None:
        c = self.core
        if not c.for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        mtype = int(getattr(m, "mission_type", 0))
        if mtype in (mav.MAV_MISSION_TYPE_MISSION, mav.MAV_MISSION_TYPE_ALL):
            c.spawn(self._clear(link, src, comp, mtype))
        else:  # fences and rally points: the boat has none
            c.mission_ack(link, src, comp, mav.MAV_MISSION_ACCEPTED, mtype)

    # -------------------------------------------------------------- download

    def on_request_list(self, link: Link, m: Any) -> None:
        if not self.core.for_us(m):
            return
        mtype = int(getattr(m, "mission_type", 0))
        n = len(self.items) if mtype == mav.MAV_MISSION_TYPE_MISSION else 0
        link.send(mav.MAVLink_mission_count_message(m.get_srcSystem(), m.get_srcComponent(),
                                                    n, mtype))

    def on_request(self, link: Link, m: Any, is_int: bool) -> None:
        c = self.core
        if not c.for_us(m):
            return
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        mtype = int(getattr(m, "mission_type", 0))
        seq = int(m.seq)
        if mtype != mav.MAV_MISSION_TYPE_MISSION or not 0 <= seq < len(self.items):
            c.mission_ack(link, src, comp, mav.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        it = self.items[seq]
        current = int(self.mission_state == mav.MISSION_STATE_ACTIVE
                      and self.wp_seqs[min(self.cur, len(self.wp_seqs) - 1)] == seq)
        if is_int:
            x, y = it.int_xy()
            link.send(mav.MAVLink_mission_item_int_message(
                src, comp, seq, it.frame, it.command, current, it.autocontinue, it.param1,
                it.param2, it.param3, it.param4, x, y, it.z, mtype))
        else:
            link.send(mav.MAVLink_mission_item_message(
                src, comp, seq, it.frame, it.command, current, it.autocontinue, it.param1,
                it.param2, it.param3, it.param4, it.x, it.y, it.z, mtype))

    def on_set_current(self, link: Link, m: Any) -> None:
        if not self.core.for_us(m):
            return
        self.core.event("mission", f"MISSION_SET_CURRENT from mavlink:{m.get_srcSystem()} "
                        "refused: a mission runs from its start (or `resume`)")
        link.send(self.current())

    # -------------------------------------------------------------- progress

    def current(self, mode: Mode | None = None) -> Any:
        """MISSION_CURRENT as it stands (in ``mode``; default the supervisor's)."""
        seq = 0
        if self.wp_seqs:
            seq = self.wp_seqs[min(self.cur, len(self.wp_seqs) - 1)]
        mode = self.core.mode if mode is None else mode
        return mav.MAVLink_mission_current_message(
            seq, len(self.items), self.mission_state, int(mode is Mode.LINES))

    def broadcast_current(self, mode: Mode | None = None) -> None:
        for ln in self.core.links:
            ln.send(self.current(mode))

    def on_status(self, st: VesselStatus) -> None:
        """The supervisor's status: when its loaded mission changed (another
        upload, the shore link's, a clear), the mission a ground station
        downloads follows it."""
        if st.mission_id == self.mission_id:
            return
        self.mission_id = st.mission_id
        pts = tuple((float(a), float(b)) for a, b in st.mission_points)
        if pts == self.wps:
            return
        up = self.uploaded
        if up is not None and up[0] == pts:
            self.items, self.wp_seqs = up[1], up[2]
        else:
            self.items, self.wp_seqs = items_from_points(pts)
        self.wps = pts
        self.cur = 0
        running = st.mode == Mode.LINES.value and bool(pts)
        self.mission_state = (mav.MISSION_STATE_NO_MISSION if not pts
                              else mav.MISSION_STATE_ACTIVE if running
                              else mav.MISSION_STATE_NOT_STARTED)
        self.broadcast_current()

    def on_directive(self, d: Directive) -> None:
        """A new directive (not a repeat of the last) from the supervisor."""
        m = d.mission
        if d.mode is Mode.LINES and m is not None and m.legs:
            if not (self.wps and m.waypoints == self.wps):
                self.items, self.wp_seqs, self.wps = items_from_mission(m, self.core.frame)
            self.cur = max(0, min(d.start_leg, len(self.wps) - 1))
            self.mission_state = mav.MISSION_STATE_ACTIVE
        elif self.mission_state == mav.MISSION_STATE_ACTIVE:
            self.mission_state = mav.MISSION_STATE_PAUSED
        self.broadcast_current(d.mode)  # the status saying it comes a moment later

    def on_guidance(self, g: GuidanceStatus) -> None:
        # the last status of a mission (complete) comes after the supervisor has
        # already switched to hold, because of it
        if g.mode != "lines" or not self.wps or not (
                self.mission_state == mav.MISSION_STATE_ACTIVE
                or (g.complete and self.mission_state == mav.MISSION_STATE_PAUSED)):
            return
        last = len(self.wps) - 1
        if g.complete:
            c = last + 1
        elif g.leg == 0 and g.along_m < 0.0:
            c = 0
        else:
            c = min(last, g.leg + 1)
        if c <= self.cur and not g.complete:
            return
        for k in range(self.cur, min(c, last + 1)):
            for ln in self.core.links:
                ln.send(mav.MAVLink_mission_item_reached_message(self.wp_seqs[k]))
        self.cur = min(c, last)
        if g.complete:
            self.mission_state = mav.MISSION_STATE_COMPLETE
        self.broadcast_current()
