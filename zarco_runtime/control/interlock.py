"""The drive interlock: the conditions under which nothing may drive the boat.

Three facts make driving unsafe whatever the mode (manual included): the
position is lost, the heading is lost, or the thruster controller is silent.
They are judged here, once, by pure functions of what was last heard; the
supervisor's failsafe table uses the same functions for its ``position_lost``,
``heading_lost`` and ``thruster_silent`` conditions, and the control task
checks them itself at every tick through a :class:`DriveInterlock`, so a
command computed between two supervisor evaluations is zero as soon as a
condition holds, not up to one evaluation later.

A condition latches, here as in the failsafe table: once seen, driving stays
unsafe until the condition has been healthy for ``failsafe.clear_after_s``, so
a condition that flaps (a thruster controller answering now and then) gives
no thrust between its flaps, even a flap too short for the supervisor to see.
The supervisor's own latch (a failsafe active from its entry until it clears)
reaches the control task with the directive (``driving_failsafes``).

Times are runtime clock seconds; a reason "" means the condition does not hold.
"""

from __future__ import annotations

import math
from typing import Protocol

from zarco_core.messages import Heading, NavState, ThrusterCommand, ThrusterStatus


def position_lost(now: float, nav: NavState | None, limit_s: float) -> tuple[str, float]:
    """(reason, onset) when no GPS position was fused for ``limit_s`` (the
    estimator dead-reckons until then) or the estimate calls its position
    invalid; ("", nan) otherwise."""
    if nav is None:
        return "no position estimate", now
    age = nav.gps_age_s + (now - nav.t)
    if age > limit_s:
        return f"no GPS position for {age:.1f} s", now - age
    if not nav.pos_valid:
        return "position estimate invalid", nav.t
    return "", math.nan


def heading_lost(now: float, last_heading_t: float | None, nav: NavState | None,
                 limit_s: float) -> tuple[str, float]:
    """(reason, onset) when no compass heading came for ``limit_s`` (or none
    ever) or the estimate calls its heading invalid."""
    if last_heading_t is None:
        return "no compass heading yet", now
    age = now - last_heading_t
    if age > limit_s:
        return f"no compass heading for {age:.1f} s", last_heading_t
    if nav is not None and not nav.heading_valid:
        return "heading estimate invalid", nav.t
    return "", math.nan


def thruster_silent(now: float, status_ref_t: float | None,
                    limit_s: float) -> tuple[str, float]:
    """(reason, onset) when the thruster controller has not answered for
    ``limit_s``: ``status_ref_t`` is its last ``$PZTHS``, or the first command
    sent to it if it never answered (None: nothing sent yet)."""
    if status_ref_t is None:
        return "", math.nan
    age = now - status_ref_t
    if age > limit_s:
        return f"no status from the thruster controller for {age:.1f} s", status_ref_t
    return "", math.nan


class Limits(Protocol):
    """The limits of the three conditions and the time a condition must have been
    healthy to clear (s): the failsafe table's (``[failsafe]``)."""

    position_lost_s: float
    heading_lost_s: float
    thruster_silent_s: float
    clear_after_s: float


class DriveInterlock:
    """What the control task knows of the three driving conditions.

    Its listeners note the last compass heading and thruster status (and the
    first command sent); :meth:`hazard` says why driving is unsafe now ("" when
    it is not), with the limits of the live failsafe table (a parameter change
    applies at once), latched: the last condition seen holds until it has been
    healthy for ``clear_after_s``.  ``thrusters``: a thruster controller is
    configured (else its silence is no condition).
    """

    def __init__(self, limits: Limits, thrusters: bool = True) -> None:
        self.limits = limits
        self.thrusters = thrusters
        self.last_heading_t: float | None = None
        self.last_status_t: float | None = None
        self.first_cmd_t: float | None = None
        #: the last condition seen: (runtime time, s; its reason)
        self.last_seen: tuple[float, str] | None = None

    def on_heading(self, m: Heading) -> None:
        self.last_heading_t = m.t

    def on_status(self, m: ThrusterStatus) -> None:
        self.last_status_t = m.t

    def on_command(self, m: ThrusterCommand) -> None:
        if self.first_cmd_t is None:
            self.first_cmd_t = m.t

    @property
    def status_ref_t(self) -> float | None:
        """The thruster controller's last answer, else the first command sent."""
        return self.last_status_t if self.last_status_t is not None else self.first_cmd_t

    def condition(self, now: float, nav: NavState | None) -> str:
        """Which of the three conditions holds now ("" when none does), unlatched."""
        lim = self.limits
        why, _ = position_lost(now, nav, lim.position_lost_s)
        if not why:
            why, _ = heading_lost(now, self.last_heading_t, nav, lim.heading_lost_s)
        if not why and self.thrusters:
            why, _ = thruster_silent(now, self.status_ref_t, lim.thruster_silent_s)
        return why

    def hazard(self, now: float, nav: NavState | None) -> str:
        """Why nothing may drive now ("" when driving is allowed): a condition that
        holds, or the last one seen until it has been healthy for ``clear_after_s``."""
        why = self.condition(now, nav)
        if why:
            self.last_seen = (now, why)
            return why
        if self.last_seen is not None:
            seen_t, was = self.last_seen
            wait = self.limits.clear_after_s
            if now - seen_t < wait:
                return f"{was}; healthy for {now - seen_t:.1f} s of the {wait:g} s to clear"
            self.last_seen = None
        return ""
