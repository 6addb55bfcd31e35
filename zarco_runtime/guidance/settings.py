"""Settings of the line guidance (``[guidance]``)."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec


@dataclass(slots=True)
class Guidance:
    switching: str = spec("cross_end", "", "when the next line starts: 'cross_end' (paper: "
                          "after crossing the end of the line) or 'anticipate' (turn early "
                          "by the turning radius)", choices=["cross_end", "anticipate"])
    turn_rate_dps: float = spec(50.0, "deg/s", "turn rate assumed by 'anticipate' (its lead "
                                "is U/r·tan(turn/2); 50 minimises the corner error here)",
                                min=1.0, max=90.0)
