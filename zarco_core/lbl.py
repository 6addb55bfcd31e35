"""The long-baseline acoustic network as configured (shared by the tracker's
configuration and the simulator's acoustic world)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.config import spec


@dataclass(slots=True)
class LblNetworkParams:
    """The long-baseline network as the tracker knows it (paper section IV).

    ``beacons[i] = [north_m, east_m, depth_m]``; ``beacon_ids[i]`` is beacon i's
    id on the wire (``$PZBAE`` field C; empty list = ids 1..N);
    ``turnaround_s[i]`` is τ_i; ``listener_beacon`` is the *index* (0-based,
    into ``beacons``) of the beacon the buoy's hydrophone sits at.
    """

    beacons: list[list[float]] = spec(
        [[0.0, 0.0, 30.0], [400.0, 50.0, 30.0], [150.0, 400.0, 30.0]], "m",
        "beacon positions [north, east, depth] in the local NED frame")
    beacon_ids: list[int] = spec([], "", "wire ids of the beacons, in the order of "
                                 "`beacons` (empty: 1..N)", min=0, max=9999)
    turnaround_s: list[float] = spec([0.1, 0.1, 0.1], "s",
                                     "turnaround τ_i of each beacon", min=0.0, max=10.0)
    auv_delay_s: float = spec(0.5, "s", "the AUV's fixed delay δ between hearing a reply "
                              "and its next interrogation", min=0.0, max=30.0)
    sound_speed_mps: float = spec(1500.0, "m/s", "sound speed c", min=1400.0, max=1600.0)
    listener_beacon: int = spec(0, "", "index (0-based) into `beacons` of the beacon the "
                                "buoy listens at", min=0, max=63)

    def validate(self) -> None:
        n = len(self.beacons)
        if n < 2:
            raise ValueError("beacons: need at least 2 beacons (the listener and one more)")
        for i, b in enumerate(self.beacons):
            if len(b) != 3:
                raise ValueError(f"beacons: beacon {i} must be [north, east, depth], got {b}")
            if not all(math.isfinite(v) for v in b):
                raise ValueError(f"beacons: beacon {i} has a non-finite coordinate")
        if self.beacon_ids and len(self.beacon_ids) != n:
            raise ValueError(f"beacon_ids: {len(self.beacon_ids)} ids for {n} beacons")
        if len(set(self.ids())) != n:
            raise ValueError("beacon_ids: ids must be distinct")
        if len(self.turnaround_s) != n:
            raise ValueError(f"turnaround_s: {len(self.turnaround_s)} values for {n} beacons")
        if not 0 <= self.listener_beacon < n:
            raise ValueError(f"listener_beacon: index {self.listener_beacon} not in 0..{n - 1}")

    def ids(self) -> list[int]:
        """Wire ids of the beacons (``beacon_ids`` or 1..N)."""
        return list(self.beacon_ids) if self.beacon_ids else list(range(1, len(self.beacons) + 1))
