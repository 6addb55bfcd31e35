"""The beacons' layout as the operator should know it: nearly on one line.

A cycle's two ranges put the AUV on two circles (to the cycle's beacon and
to the listener), which meet at two points mirrored across the line through
the two beacons; the other beacons' ranges tell the two apart (the tracker's
mirror choice, :mod:`.assembly`).  When every beacon lies close to one line,
every range is almost the same on either side of it: an AUV running along
that line, or turning near it, can be tracked on its mirror side, minutes
long, and the sound-speed estimate takes up the small misfit the beacons'
distance from the line leaves.  Nothing in the ranges tells the side; only a
layout that is not a line does.  With two beacons the layout is always a
line (the tracker keeps to the side its prior and the track say).

:func:`line_spread` measures it (horizontal NED positions, m);
:func:`line_warning` words it for the operator when the beacons lie within
``LINE_RATIO`` of their span of one line (three beacons or more).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

#: beacons within this fraction of their span of one line: the operator is told
LINE_RATIO = 0.05


def line_spread(north: Sequence[float], east: Sequence[float]) -> tuple[float, float]:
    """(width, span) of the beacons' horizontal layout (m): the largest
    distance of a beacon from the line that fits them best (total least
    squares), and their extent along it."""
    n = len(north)
    mn, me = sum(north) / n, sum(east) / n
    sxx = sum((x - mn) ** 2 for x in north)
    syy = sum((y - me) ** 2 for y in east)
    sxy = sum((x - mn) * (y - me) for x, y in zip(north, east, strict=True))
    th = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    ux, uy = math.cos(th), math.sin(th)
    along = [(x - mn) * ux + (y - me) * uy for x, y in zip(north, east, strict=True)]
    across = [abs(-(x - mn) * uy + (y - me) * ux) for x, y in zip(north, east, strict=True)]
    return max(across), max(along) - min(along)


def line_warning(north: Sequence[float], east: Sequence[float]) -> str | None:
    """The operator's warning when three beacons or more lie within
    ``LINE_RATIO`` of their span of one line, else None."""
    if len(north) < 3:
        return None
    width, span = line_spread(north, east)
    if span <= 0.0 or width > LINE_RATIO * span:
        return None
    return (f"beacons nearly on one line (all within {width:.1f} m of it over {span:.0f} m): "
            "an AUV near that line can be tracked on its mirror side; "
            "move a beacon off the line")
