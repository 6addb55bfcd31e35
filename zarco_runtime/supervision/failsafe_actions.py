"""The failsafe table evaluated, and what the supervisor does about it.

:func:`evaluate` runs at ``supervisor.rate_hz``: it sets home from the first
position, judges the conditions (:mod:`.failsafes`, in every mode), takes the
action of each failsafe that enters (:func:`apply`: the more severe wins; an
``idle`` action disarms; a failsafe never sets a still boat moving) and, when
the last one clears, ``failsafe.after_clear`` for a boat a ``hold`` or
``return`` action kept under way (:func:`after_clear`).  The active driving
failsafes go to the control task with the directive: zero thrust from a
failsafe's entry until it clears, whatever its action.  It also arms and
starts a pending ``mission.autostart`` once the checks pass
(:func:`autostart`).  Functions of the
:class:`~zarco_runtime.supervision.supervisor.Supervisor`, which owns the
state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from zarco_core.messages import Mode
from zarco_runtime.guidance.mission import Mission
from zarco_runtime.supervision import arming, command_handlers
from zarco_runtime.supervision.failsafes import SEVERITY, Inputs

if TYPE_CHECKING:
    from zarco_runtime.supervision.supervisor import Supervisor


def inputs(sup: Supervisor, now: float) -> Inputs:
    """What the failsafe conditions are judged on now."""
    pos = sup.position()
    outside = ""
    if sup.fence.enabled and pos is not None:
        outside = sup.fence.outside(*pos)
    auv_lost = ""
    if sup.mode is Mode.FOLLOW:
        tr = sup.track.value
        # lost once it was held since following began (acquiring is not losing)
        if tr is not None and tr.t >= sup.directive_t0 and not tr.lost:
            sup.auv_held = True
        if tr is not None and tr.lost and sup.auv_held:
            auv_lost = "AUV track lost"
    status_ref = None
    if sup.caps.thrusters:
        status_ref = sup.last_status_t if sup.last_status_t is not None \
            else sup.first_cmd_t
    failed = [c for c, s in sup.health.components.items()
              if s.state != "running" and c in sup.control_path]
    return Inputs(now, sup.mode, sup.nav.value, sup.last_heading_t, status_ref,
                  sup.heartbeat_t, outside, auv_lost, failed, sup.armed)


def evaluate(sup: Supervisor, now: float) -> None:
    """One evaluation of the failsafe table (and of a pending autostart)."""
    sup.last_eval = now
    if sup.home is None:
        p = sup.position()
        if p is not None:
            sup.home = p
            sup.fence.home = p
            sup.status_due = True  # ground stations learn home now, not a period later
            lat, lon, _ = sup.frame.to_geodetic(*p)
            sup.event("mission", f"home set at {lat:.6f}, {lon:.6f} (first position)")
    for tr in sup.failsafes.evaluate(inputs(sup, now)):
        sup.status_due = True
        if tr.entered:
            sup.event("failsafe", f"{tr.name}: {tr.reason}; action {tr.action} "
                      f"(condition since {now - tr.t_condition:.2f} s)"
                      + ("" if sup.armed else "; disarmed already"))
            apply(sup, tr.action, f"failsafe {tr.name}: {tr.reason}")
        else:
            sup.event("failsafe", f"{tr.name} {tr.reason}")
            if not sup.failsafes.active:
                after_clear(sup)
    if sup.directive.driving_failsafes != sup.driving_failsafes():
        sup.publish_directive()  # the control task holds the thrust until they clear
    bm = sup.boot.mission
    if sup.pending_start and bm is not None:
        autostart(sup, bm)


def autostart(sup: Supervisor, bm: Mission) -> None:
    """``mission.autostart``: arm once the checks pass, then start the mission."""
    if not sup.armed:
        if arming.arm_refusal(sup):
            return
        arming.arm(sup, "autostart (mission.autostart = true)")
    if arming.cannot(sup, Mode.LINES if bm.kind == "lines" else Mode.FOLLOW):
        return
    sup.pending_start = False
    why = command_handlers.start(sup, bm, 0, "autostart")
    if why:
        sup.event("mission", f"autostart refused: {why}")


def apply(sup: Supervisor, action: str, reason: str) -> None:
    """A failsafe entered: take its ``action`` (the more severe one wins)."""
    if action == "continue" or not sup.armed:
        return
    if action == "idle":
        sup.fs_interrupted = None
        arming.disarm(sup, reason, by_failsafe=True)
        return
    if sup.mode is Mode.IDLE:
        return  # armed but still: a failsafe never sets the boat moving
    current = {Mode.HOLD: "hold", Mode.RETURN: "return"}.get(sup.mode)
    if current is not None and SEVERITY[current] >= SEVERITY[action]:
        return
    if sup.fs_interrupted is None:
        leg = sup.progress.leg if sup.mode is Mode.LINES else 0
        sup.fs_interrupted = (sup.mode, sup.mission, leg)
    if action == "hold":
        p = sup.position()
        if p is None:
            arming.disarm(sup, reason + " (no position to hold: idle)", by_failsafe=True)
        else:
            sup.set_mode(Mode.HOLD, reason, point=p, by_failsafe=True)
    elif action == "return":
        if sup.home is None or sup.position() is None:
            arming.disarm(sup, reason + " (cannot return: idle)", by_failsafe=True)
        else:
            sup.set_mode(Mode.RETURN, reason, point=sup.home, by_failsafe=True)


def after_clear(sup: Supervisor) -> None:
    """Every failsafe has cleared: ``after_clear`` for a boat a failsafe kept
    under way (hold, return); a boat an ``idle`` action stopped stays idle and
    disarmed until an operator acts."""
    interrupted, sup.fs_interrupted = sup.fs_interrupted, None
    applied, sup.fs_applied = sup.fs_applied, False
    if not applied or not sup.armed or sup.mode not in (Mode.HOLD, Mode.RETURN):
        sup.event("failsafe", f"failsafes cleared; staying {sup.mode.value}"
                  + ("" if sup.armed else " and disarmed: arm to go on"))
        return  # the operator took over since, or the boat was stopped
    policy = sup.cfg.failsafe.after_clear
    if policy == "resume" and interrupted is not None:
        mode, mission, leg = interrupted
        why = arming.cannot(sup, mode)
        if not why:
            sup.set_mode(mode, "failsafes cleared: resuming", mission=mission,
                         start_leg=leg, point=sup.home if mode is Mode.RETURN else None,
                         keep_operator=True)
            return
        sup.event("failsafe", f"cannot resume: {why}")
    if policy in ("hold", "resume"):
        p = sup.position()
        if p is not None and not arming.cannot(sup, Mode.HOLD):
            sup.set_mode(Mode.HOLD, "failsafes cleared: holding here; send resume to "
                         "continue the mission", point=p, keep_operator=True)
            return
    arming.disarm(sup, "failsafes cleared: idle (failsafe.after_clear)")
