"""The supervisor's commands: each one handled, answered once.

:func:`on_command` takes a :class:`~zarco_core.messages.Command` (typed
arguments, :mod:`zarco_core.commands`) from any source, rate limited per
source (``stop`` and ``disarm`` never are), and publishes exactly one
:class:`~zarco_core.messages.CommandAck`: accepted, or refused with a reason a
person can read.  Nothing a command carries can raise out of it: an error
while handling one is a refusal and a counted fault, never a restart.  The
handlers (:func:`mode`, :func:`hold`, :func:`follow`, :func:`mission`,
:func:`start`, :func:`resume`, :func:`param`) return "" when done, else why
not.  Functions of the
:class:`~zarco_runtime.supervision.supervisor.Supervisor`, which owns the
state.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from zarco_core.commands import (
    ArmArgs,
    DisarmArgs,
    FollowArgs,
    MissionArgs,
    ModeArgs,
    ParamArgs,
    ResumeArgs,
    StopArgs,
    ThrustArgs,
)
from zarco_core.messages import Command, CommandAck, Fault, Mode, ParamChange
from zarco_runtime.guidance.directive import ManualThrust
from zarco_runtime.guidance.mission import Mission
from zarco_runtime.supervision import arming, params
from zarco_runtime.supervision.geofence import Fence
from zarco_runtime.supervision.missions import lines_mission
from zarco_runtime.supervision.state_file import SavedMission
from zarco_runtime.tracking.plan import PlanError, geodetic_plan

if TYPE_CHECKING:
    from zarco_runtime.supervision.supervisor import Supervisor

log = logging.getLogger("zarco.supervisor")


def on_command(sup: Supervisor, cmd: Command) -> None:
    """Handle one command; publishes exactly one CommandAck.  Nothing a command
    carries can raise out of here: an error in handling it is a refusal and a
    counted fault (``stop`` and ``disarm`` still stop the boat)."""
    a = cmd.args
    safe = isinstance(a, (StopArgs, DisarmArgs))
    try:
        if not safe and not sup.buckets.take(cmd.source, sup.now()):
            s = sup.cfg.supervisor
            reason = (f"rate limited: more than {s.command_rate_hz:g} commands a second "
                      f"(burst {s.command_burst}) from {cmd.source}")
        else:
            reason = handle(sup, cmd)
    except Exception as exc:  # a command never restarts the supervisor
        sup.command_faults += 1
        log.exception("command %s from %s", cmd.name, cmd.source)
        reason = f"not handled: internal error ({type(exc).__name__})"
        sup.bus.publish(Fault(sup.now(), "supervisor",
                              f"command {cmd.name} from {cmd.source}: {exc!r}"[:300]))
        if safe:
            sup.armed, sup.pending_start = False, False
            sup.set_mode(Mode.IDLE, f"{cmd.name} from {cmd.source}")
            reason = ""
    sup.bus.publish(CommandAck(sup.now(), cmd.id, cmd.source, cmd.name, not reason,
                               sup.mode.value, reason))


def on_ack(sup: Supervisor, ack: CommandAck) -> None:
    """Every acknowledgement (ours, and a link's refusal of a payload): counted
    and told, within each source's event budget."""
    sup.acks["accepted" if ack.ok else "refused"] += 1
    if ack.ok and ack.name == "thrust":
        sup.acks["thrust"] += 1  # a lease renewal: counted, not told
        return
    if sup.ack_events.allow(ack.source, ack.t):
        sup.event("ack", f"{ack.name} from {ack.source}: "
                  + ("accepted" if ack.ok else f"refused: {ack.reason}"))


def handle(sup: Supervisor, cmd: Command) -> str:
    """Carry out ``cmd``: "" when done, else why it is refused."""
    a = cmd.args
    src = cmd.source
    if isinstance(a, (StopArgs, DisarmArgs)):
        arming.disarm(sup, f"{cmd.name} from {src}")
        return ""
    if isinstance(a, ArmArgs):
        why = arming.arm_refusal(sup)
        if why:
            return why
        if not sup.armed:
            arming.arm(sup, src)
        return ""
    if isinstance(a, ParamArgs):
        return param(sup, cmd, a)
    if isinstance(a, MissionArgs):
        return mission(sup, a, src)
    if isinstance(a, ModeArgs):
        return mode(sup, a, src)
    if isinstance(a, FollowArgs):
        return follow(sup, src, a)
    if isinstance(a, ThrustArgs):
        if not sup.armed:
            return "disarmed"
        if sup.mode is not Mode.MANUAL:
            return "not in manual mode"
        t = sup.now()
        sup.bus.publish(ManualThrust(t, a.u1, a.u2, t + sup.cfg.supervisor.manual_lease_s))
        return ""
    if isinstance(a, ResumeArgs):
        return resume(sup, src)
    return f"{cmd.name}: not handled by this supervisor"


def mode(sup: Supervisor, a: ModeArgs, src: str) -> str:
    """``mode``: idle at once; a moving mode once armed and ready."""
    wanted = a.mode
    if wanted is Mode.IDLE:
        sup.pending_start = False
        sup.set_mode(Mode.IDLE, f"mode idle from {src}")
        return ""
    if not sup.armed:
        return "disarmed"
    if wanted is Mode.HOLD:
        return hold(sup, a, src)
    if wanted is Mode.FOLLOW:
        return follow(sup, src, None)
    if wanted is Mode.LINES:
        m = sup.loaded or (sup.saved.mission if sup.saved and not sup.saved.complete
                           and sup.saved.mission.kind == "lines" else None)
        if m is None:
            return "no mission loaded"
        return start(sup, m, 0, src)
    why = arming.cannot(sup, wanted)
    if why:
        return why
    if wanted is Mode.RETURN:
        sup.set_mode(Mode.RETURN, f"return from {src}", point=sup.home)
    else:
        sup.set_mode(Mode.MANUAL, f"manual from {src}")
    return ""


def hold(sup: Supervisor, a: ModeArgs, src: str) -> str:
    """Hold at the command's point (inside the geofence), else where the boat is."""
    why = arming.cannot(sup, Mode.HOLD)
    if why:
        return why
    if a.lat_deg is not None and a.lon_deg is not None:
        point = sup.frame.to_ned(a.lat_deg, a.lon_deg)
        out = sup.fence.outside(*point) if sup.fence.enabled else ""
        if out:
            return f"lat_deg, lon_deg: hold point outside the geofence ({out})"
    else:
        p = sup.position()
        if p is None:
            return "no valid position"
        point = p
    sup.set_mode(Mode.HOLD, f"hold from {src}", point=point)
    return ""


def follow(sup: Supervisor, src: str, a: FollowArgs | None, m: Mission | None = None) -> str:
    """Follow the AUV: with the mission ``m`` (a resumed or configured one), or
    with the command's ``auv_plan`` ([[lat_deg, lon_deg], ...]; [] for none),
    or without one, with the configured follow mission's plan."""
    why = arming.cannot(sup, Mode.FOLLOW)
    if why:
        return why
    if m is None:
        boot = sup.boot.mission
        plan = boot.auv_plan if boot is not None and boot.kind == "follow" else ()
        sup.plan_source = "mission"
        if a is not None and a.auv_plan is not None:
            try:
                plan = geodetic_plan(a.auv_plan, sup.frame.to_ned)
            except PlanError as exc:
                return exc.named("auv_plan")
            sup.plan_source = src
        m = Mission("follow", name="follow", auv_plan=plan)
    else:
        sup.plan_source = "mission" if m is sup.boot.mission else src
    sup.saved = SavedMission(m)
    sup.save_state()
    sup.set_mode(Mode.FOLLOW, f"follow from {src}"
                 + (f" with an AUV plan of {len(m.auv_plan)} points" if m.auv_plan
                    else ""), mission=m)
    return ""


def mission(sup: Supervisor, a: MissionArgs, src: str) -> str:
    """``mission``: clear the loaded one, load one, or load and start it."""
    if a.clear:
        if sup.mode is Mode.LINES:
            return "a mission is running: stop or hold first"
        sup.loaded = None
        if sup.saved is not None and sup.saved.mission.kind == "lines":
            sup.saved.complete = True  # nothing left to start or resume
            sup.save_state()
        sup.status_due = True
        sup.event("mission", f"loaded mission cleared by {src}")
        return ""
    if a.start and not sup.armed:
        return "disarmed"
    m = lines_mission(a, sup.frame, sup.fence, sup.cfg.supervisor.max_speed_mps, src)
    if isinstance(m, str):
        return m
    if a.start:
        return start(sup, m, a.start_leg, src)
    sup.loaded = m
    sup.status_due = True
    sup.event("mission", f"mission loaded: {m.name}")
    return ""


def start(sup: Supervisor, m: Mission, leg: int, src: str) -> str:
    """Start mission ``m`` (lines from leg ``leg``, or follow) and remember it."""
    if m.kind == "follow":
        return follow(sup, src, None, m)
    why = arming.cannot(sup, Mode.LINES)
    if why:
        return why
    sup.loaded = m
    sup.saved = SavedMission(m, leg)
    sup.save_state()
    sup.set_mode(Mode.LINES, f"mission {m.name} from {src}"
                 + (f", from leg {leg + 1}" if leg else ""), mission=m, start_leg=leg)
    return ""


def resume(sup: Supervisor, src: str) -> str:
    """Continue the last mission (the state file's) from the leg it was on."""
    if not sup.armed:
        return "disarmed"
    s = sup.saved
    if s is None:
        return "no mission to resume"
    if s.complete:
        return f"the last mission ({s.mission.name}) is complete"
    return start(sup, s.mission, s.leg, f"{src} (resume)")


def param(sup: Supervisor, cmd: Command, a: ParamArgs) -> str:
    """Change one parameter of the live configuration, publish and tell it."""
    try:
        old, new = params.apply(sup.cfg, a.name, a.value, arming.under_way(sup))
    except params.ParamRefused as exc:
        return str(exc)
    if a.name.startswith("geofence."):
        home = sup.fence.home
        sup.fence = Fence(sup.cfg.geofence, sup.frame)
        sup.fence.home = home
    sup.bus.publish(ParamChange(sup.now(), a.name, new, old, cmd.source, cmd.id))
    sup.status_due = True
    shown = repr(new) if len(repr(new)) <= 80 else f"{repr(new)[:77]}..."
    sup.event("param", f"{a.name} = {shown} (was {old!r}) by {cmd.source}")
    return ""
