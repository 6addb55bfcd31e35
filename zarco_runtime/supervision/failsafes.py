"""The failsafe table, evaluated: conditions → entries and exits (pure, no I/O).

The supervisor gathers what the conditions are judged on (:class:`Inputs`)
and calls :meth:`FailsafeMonitor.evaluate` at its rate; the monitor says
which failsafes entered (condition true for its time) and which cleared
(condition false for ``clear_after_s``: a failsafe latches), each with a
reason a person can read.  Conditions are judged in every mode, so a
failsafe whose action stopped the boat does not clear because the boat
stopped.  The driving conditions (position, heading, thruster controller)
are the drive interlock's own functions, the very judgement the control task
applies at every tick.  What to do about it is the supervisor's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from zarco_core.messages import Mode, NavState
from zarco_runtime.control.interlock import heading_lost, position_lost, thruster_silent
from zarco_runtime.supervision.settings import CONDITIONS, Failsafe

#: severity of the actions: the most severe active one wins
SEVERITY = {"continue": 0, "return": 1, "hold": 2, "idle": 3}
#: the conditions under which nothing drives (zero thrust while one is active)
DRIVING = frozenset({"position_lost", "heading_lost", "thruster_silent"})


@dataclass(slots=True)
class Inputs:
    """What the conditions are judged on, at time ``now`` (runtime clock, s).

    ``mode`` is the vessel's mode and ``armed`` whether it is armed;
    ``last_heading_t`` the time of the last compass heading (None: never);
    ``status_ref_t`` when the thruster controller last answered, or when the
    first command was sent to it if it never did (None: nothing sent yet, or no
    thruster controller configured); ``heartbeat_t`` the last operator
    heartbeat on the supervising link (None: none yet: the link is not
    watched); ``outside_fence`` why the position is outside the geofence (""
    inside); ``auv_lost`` why the AUV track is lost ("" not lost); ``failed``
    the control-path components failed and not yet running again.
    """

    now: float
    mode: Mode
    nav: NavState | None
    last_heading_t: float | None
    status_ref_t: float | None
    heartbeat_t: float | None
    outside_fence: str = ""
    auv_lost: str = ""
    failed: list[str] = field(default_factory=list)
    armed: bool = False


@dataclass(slots=True)
class Transition:
    """A failsafe entered (``entered``) or cleared, with its reason and action."""

    name: str
    entered: bool
    reason: str
    action: str
    t_condition: float


class FailsafeMonitor:
    """Keeps, per condition, since when it holds and whether it is active."""

    def __init__(self, cfg: Failsafe) -> None:
        self.cfg = cfg
        self.since: dict[str, float | None] = dict.fromkeys(CONDITIONS)
        self.false_since: dict[str, float | None] = dict.fromkeys(CONDITIONS)
        self.active: dict[str, str] = {}  # name → reason when it entered

    def condition(self, name: str, i: Inputs) -> tuple[str, float]:
        """(reason, onset) if condition ``name`` holds now, else ("", nan).  The onset
        is when the condition (the fault) began, for the delay and the report."""
        cfg = self.cfg
        if name == "position_lost":  # judged from the first fix (before: not armable)
            if i.nav is None or not math.isfinite(i.nav.gps_age_s):
                return "", math.nan
            return position_lost(i.now, i.nav, cfg.position_lost_s)
        if name == "heading_lost":  # judged from the first heading (before: not armable)
            if i.last_heading_t is None:
                return "", math.nan
            return heading_lost(i.now, i.last_heading_t, i.nav, cfg.heading_lost_s)
        if name == "thruster_silent":
            return thruster_silent(i.now, i.status_ref_t, cfg.thruster_silent_s)
        if name == "link_lost":
            if not i.armed or i.heartbeat_t is None:
                return "", math.nan
            age = i.now - i.heartbeat_t
            if age > cfg.link_lost_s:
                return f"no operator heartbeat ({cfg.link}) for {age:.0f} s", i.heartbeat_t
            return "", math.nan
        if name == "geofence":
            return (i.outside_fence, i.now) if i.outside_fence else ("", math.nan)
        if name == "auv_lost":
            return (i.auv_lost, i.now) if i.mode is Mode.FOLLOW and i.auv_lost \
                else ("", math.nan)
        if name == "component_failed":
            if not i.failed:
                return "", math.nan
            return f"component failed: {', '.join(sorted(i.failed))}", i.now
        raise KeyError(name)

    def evaluate(self, i: Inputs) -> list[Transition]:
        """Entries and exits at ``i.now``."""
        out: list[Transition] = []
        cfg = self.cfg
        for name in CONDITIONS:
            reason, onset = self.condition(name, i)
            if reason:
                self.false_since[name] = None
                since = self.since[name]
                if since is None:
                    since = onset if math.isfinite(onset) else i.now
                    self.since[name] = since
                # age-based conditions already waited their time; others wait theirs
                wait = 0.0 if name in ("position_lost", "heading_lost", "thruster_silent",
                                       "link_lost") else cfg.delay_s(name)
                if name not in self.active and i.now - since >= wait:
                    self.active[name] = reason
                    out.append(Transition(name, True, reason, cfg.action(name), since))
            else:
                self.since[name] = None
                if name in self.active:
                    fs = self.false_since[name]
                    if fs is None:
                        self.false_since[name] = fs = i.now
                    if i.now - fs >= cfg.clear_after_s:
                        self.false_since[name] = None
                        was = self.active.pop(name)
                        out.append(Transition(name, False, f"cleared ({was})",
                                              cfg.action(name), fs))
        return out

    def driving(self) -> list[str]:
        """The active failsafes under which nothing may drive."""
        return [n for n in self.active if n in DRIVING]
