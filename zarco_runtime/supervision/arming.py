"""Arming, and whether a mode may be entered now.

The vessel boots disarmed.  ``arm`` is accepted only with a valid position and
heading, the thruster controller answering and no failsafe active
(:func:`arm_refusal`); ``disarm``, ``stop`` and an ``idle`` failsafe go idle
and disarmed (:func:`disarm`).  A moving mode is refused, with its reason,
while disarmed or when the boat cannot do it (:func:`cannot`).  Arming changes
reach the control task with the directive, republished at once.  Functions of
the :class:`~zarco_runtime.supervision.supervisor.Supervisor`, which owns the
state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from zarco_core.messages import MOVING, Mode

if TYPE_CHECKING:
    from zarco_runtime.supervision.supervisor import Supervisor


def arm(sup: Supervisor, by: str) -> None:
    """Armed: thrust is allowed (the boat stays in its mode; idle does not move)."""
    sup.armed = True
    sup.event("arming", f"armed by {by}")
    sup.publish_directive()


def disarm(sup: Supervisor, reason: str, *, by_failsafe: bool = False) -> None:
    """Idle and disarmed (stop, disarm, an ``idle`` failsafe)."""
    was = sup.armed
    sup.armed = False
    sup.pending_start = False
    if sup.mode is not Mode.IDLE:
        sup.set_mode(Mode.IDLE, reason, by_failsafe=by_failsafe)
    else:
        sup.publish_directive()
    if was:
        sup.event("arming", f"disarmed: {reason}")


#: how an operator reads each device of the configuration in a refusal
_DEVICE_NAMES = {"thrusters": "thrusters", "gps": "GPS", "compass": "compass",
                 "buoy": "buoy feed"}


def disabled(sup: Supervisor, *devices: str) -> str:
    """The refusal for the first of ``devices`` the configuration disables ("" if none)."""
    for d in devices:
        if not getattr(sup.caps, d):
            return f"{_DEVICE_NAMES[d]} disabled (devices.{d}.enabled = false)"
    return ""


def arm_refusal(sup: Supervisor) -> str:
    """Why the boat cannot be armed now ("" when it can)."""
    why = disabled(sup, "thrusters", "gps", "compass")
    if why:
        return why
    n = sup.nav.value
    if n is None or not n.pos_valid:
        return "no valid position"
    now = sup.now()
    if not n.heading_valid or sup.last_heading_t is None or \
            now - sup.last_heading_t > sup.cfg.failsafe.heading_lost_s:
        return "no valid heading"
    if sup.last_status_t is None or \
            now - sup.last_status_t > sup.cfg.failsafe.thruster_silent_s:
        return "the thruster controller is not answering"
    if sup.failsafes.active:
        return "failsafe active: " + ", ".join(
            f"{k} ({v})" for k, v in sorted(sup.failsafes.active.items()))
    return ""


def cannot(sup: Supervisor, mode: Mode) -> str:
    """Why ``mode`` cannot be entered now ("" when it can)."""
    if mode is Mode.IDLE:
        return ""
    if not sup.armed:
        return "disarmed"
    if not sup.caps.thrusters:
        return disabled(sup, "thrusters")
    if "thruster_silent" in sup.failsafes.active:
        return "the thruster controller is not answering"
    if "component_failed" in sup.failsafes.active:
        return sup.failsafes.active["component_failed"]
    if mode is Mode.MANUAL:
        return ""
    why = disabled(sup, "gps", "compass")
    if why:
        return why
    n = sup.nav.value
    if n is None or not n.pos_valid:
        return "no valid position"
    if not n.heading_valid:
        return "no valid heading"
    if sup.last_heading_t is None or \
            sup.now() - sup.last_heading_t > sup.cfg.failsafe.heading_lost_s:
        return "no compass heading"
    if mode is Mode.FOLLOW and not sup.caps.buoy:
        return disabled(sup, "buoy")
    if mode is Mode.RETURN and sup.home is None:
        return "home unknown"
    return ""


def under_way(sup: Supervisor) -> str:
    """The mode the boat is under way in ("" when idle or disarmed)."""
    return sup.mode.value if sup.armed and sup.mode in MOVING else ""
