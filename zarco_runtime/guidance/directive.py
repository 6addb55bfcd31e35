"""What the supervisor tells the control loop to do (supervisor → control).

The supervisor owns the mode; the control task executes the latest
:class:`Directive`.  A directive is republished periodically even when
nothing changes: the control loop treats one older than its timeout as
``idle`` (a supervisor that stopped cannot leave the boat driving).
``seq`` changes whenever what to do changes, so the control task rebuilds
its guidance exactly then.
"""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.messages import Mode
from zarco_runtime.guidance.mission import Mission


@dataclass(slots=True)
class Directive:
    """The mode to execute, with its mission (lines: from leg ``start_leg``) or
    its point (hold, return: NED metres).  ``reason`` says why (for status);
    ``since`` is when this directive was first given (``t`` is when it was last
    republished); ``armed`` whether thrust is allowed at all (a directive that
    is not armed gives zero thrust whatever its mode); ``driving_failsafes``
    the driving failsafes active (``position_lost``, ``heading_lost``,
    ``thruster_silent``): from a failsafe's entry until it clears (its
    condition healthy for ``failsafe.clear_after_s``) the directive gives zero
    thrust whatever its mode and the failsafe's action."""

    t: float
    seq: int
    mode: Mode
    mission: Mission | None = None
    start_leg: int = 0
    point: tuple[float, float] | None = None
    reason: str = ""
    since: float = -1.0
    armed: bool = False
    driving_failsafes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.since < 0.0:
            self.since = self.t


@dataclass(slots=True)
class ManualThrust:
    """The operator's thruster commands (−100..100), valid until runtime time
    ``until`` (the lease); zero thrust after it."""

    t: float
    u1: float
    u2: float
    until: float
