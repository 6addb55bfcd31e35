"""Heading-source fault monitors and the validity of the estimate.

* A compass (or any heading source, by message source: a receiver can freeze
  too): a reading repeated ``frozen_count`` times while the gyro turned more
  than ``frozen_turn_deg`` is *frozen*; steps not explained by the gyro larger
  than ``jump_deg``, ``jump_count`` times in ``jump_window_s``, mean
  *jumping*.  Either flag rejects that source's readings until it behaves
  again.
* Validity: without GPS the filter dead-reckons (heading from compass and gyro,
  speed through the water from the model or held, sway model, current) with
  growing covariance; ``pos_valid`` goes false after ``dr_max_s`` without a
  fused fix or when the position σ (worse axis) exceeds ``pos_sigma_max_m``;
  ``heading_valid`` after ``heading_dr_max_s`` without a fused heading or when
  its σ exceeds ``heading_sigma_max_deg``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from zarco_core.angles import wrap
from zarco_core.messages import Heading
from zarco_runtime.navigation.ekf.layout import PPSI, PXX, PYY, Counters, FilterState
from zarco_runtime.navigation.ekf_config import EkfSettings


@dataclass(slots=True)
class CompassMonitor:
    """Frozen / jumping detection for one compass (message source)."""

    last_raw: float = math.nan
    repeats: int = 0
    psi_at_change: float = math.nan
    frozen: bool = False
    last_z: float = math.nan
    last_psi: float = math.nan
    last_t: float = -math.inf
    jumps: deque[float] = field(default_factory=deque)
    jumping: bool = False


class HeadingMonitors:
    """The fault detectors of every heading source, by message source."""

    def __init__(self, cfg: EkfSettings, counters: Counters) -> None:
        self.cfg = cfg
        self.counters = counters
        self._frozen_turn = math.radians(cfg.frozen_turn_deg)
        self._jump = math.radians(cfg.jump_deg)
        self.sources: dict[str, CompassMonitor] = {}

    def ok(self, m: Heading, z: float, tov: float, psi: float, has_gyro: bool) -> bool:
        """Frozen / jumping detection of a heading source at arrival of reading ``m``
        (``z`` rad true, valid at ``tov`` s; ``psi``: the filter's heading then, NaN
        if none); False: reject this reading."""
        cfg = self.cfg
        count = self.counters.count
        mon = self.sources.get(m.source)
        if mon is None:
            mon = self.sources[m.source] = CompassMonitor()
        # frozen: the same raw value again and again while the gyro says we turn
        if m.raw_deg == mon.last_raw:
            mon.repeats += 1
            if (not mon.frozen and mon.repeats + 1 >= cfg.frozen_count and has_gyro
                    and abs(wrap(psi - mon.psi_at_change)) > self._frozen_turn):
                mon.frozen = True
                count("compass_frozen")
        else:
            mon.last_raw = m.raw_deg
            mon.repeats = 0
            mon.psi_at_change = psi
            mon.frozen = False
        # jumping: steps the gyro does not explain
        if tov - mon.last_t < 1.0 and math.isfinite(psi) and math.isfinite(mon.last_psi):
            step = wrap((z - mon.last_z) - (psi - mon.last_psi))
            if abs(step) > self._jump:
                mon.jumps.append(tov)
        mon.last_z, mon.last_psi, mon.last_t = z, psi, tov
        jumps = mon.jumps
        while jumps and jumps[0] < tov - cfg.jump_window_s:
            jumps.popleft()
        if not mon.jumping and len(jumps) >= cfg.jump_count:
            mon.jumping = True
            count("compass_jumping")
        elif mon.jumping and (not jumps or tov - jumps[-1] > cfg.jump_clear_s):
            mon.jumping = False
        if mon.frozen or mon.jumping:
            count("compass_rejected_fault")
            return False
        return True

    def faults(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """The sources flagged frozen, and those flagged jumping."""
        frozen = tuple(k for k, v in self.sources.items() if v.frozen)
        jumping = tuple(k for k, v in self.sources.items() if v.jumping)
        return frozen, jumping


class Validity:
    """Whether the position and the heading of a filter state are fit to steer by."""

    def __init__(self, cfg: EkfSettings) -> None:
        self.cfg = cfg
        self.pos_var_max = cfg.pos_sigma_max_m**2
        self.hdg_var_max = math.radians(cfg.heading_sigma_max_deg) ** 2

    def __call__(self, c: FilterState, t: float) -> tuple[bool, bool]:
        """(position valid, heading valid) of ``c`` at ``t`` (s)."""
        cfg = self.cfg
        item = c.P.item
        pos_valid = (c.pos_init and t - c.t_pos <= cfg.dr_max_s
                     and max(item(PXX), item(PYY)) <= self.pos_var_max)
        hdg_valid = (c.hdg_init and t - c.t_hdg <= cfg.heading_dr_max_s
                     and item(PPSI) <= self.hdg_var_max)
        return pos_valid, hdg_valid
