"""The vessel's modes (one supervisor owns the current one)."""

from __future__ import annotations

import enum


class Mode(enum.StrEnum):
    """The vessel's modes; one supervisor owns the current one.

    ``idle`` zero thrust; ``manual`` the operator's U1, U2 for a lease;
    ``lines`` line tracking along a mission; ``follow`` following the AUV;
    ``hold`` station keeping at a point; ``return`` go home, then hold.
    """

    IDLE = "idle"
    MANUAL = "manual"
    LINES = "lines"
    FOLLOW = "follow"
    HOLD = "hold"
    RETURN = "return"


#: modes in which the vessel moves on its own (navigation failsafes apply)
UNDER_WAY = frozenset({Mode.LINES, Mode.FOLLOW, Mode.HOLD, Mode.RETURN})
#: modes that make the vessel move at all (refused while disarmed)
MOVING = UNDER_WAY | {Mode.MANUAL}
