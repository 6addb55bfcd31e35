"""Weak arrivals: an SNR far below its kind's recent ones (a late multipath copy,
a false detection) is told from the scatter of the direct arrivals."""

from __future__ import annotations

import math
import random

import pytest

from zarco_runtime.tracking.weak import MIN_HISTORY, WeakArrivals


def _rates(seed: int, sigma_db: float, copy_loss_db: float, n: int = 4000
           ) -> tuple[float, float]:
    """Fractions of direct arrivals and of copies called weak, over ``n``
    interrogations at a level of 20 dB with scatter ``sigma_db``, one in ten
    followed by a copy ``copy_loss_db`` down (with its own scatter)."""
    rng = random.Random(seed)
    weak = WeakArrivals()
    direct = [0, 0]
    copies = [0, 0]
    for k in range(n):
        hit = weak.weak("I", k % 3, rng.gauss(20.0, sigma_db))
        if k >= MIN_HISTORY:
            direct[0] += hit
            direct[1] += 1
        if rng.random() < 0.1:
            hit = weak.weak("I", k % 3, rng.gauss(20.0 - copy_loss_db, sigma_db))
            if k >= MIN_HISTORY:
                copies[0] += hit
                copies[1] += 1
    return direct[0] / direct[1], copies[0] / copies[1]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_copy_6_db_down_is_often_weak_a_direct_arrival_almost_never(seed: int) -> None:
    # Gaussian scatter of 2 dB: a copy's deficit is N(6, 2) against a threshold of
    # 6 dB or a little more (3σ, the scatter measured over 21 arrivals, copies
    # among them): above it for somewhat under half the copies; a direct
    # arrival's deficit N(0, 2) almost never (3σ: 0.13 % for a known σ)
    direct, copies = _rates(seed, 2.0, 6.0)
    assert copies >= 0.3
    assert direct <= 0.01


@pytest.mark.parametrize("seed", [1, 2])
def test_a_fading_channel_widens_the_threshold(seed: int) -> None:
    # 6 dB of scatter: the threshold is about 18 dB, a copy 6 dB down is rarely
    # told from the direct arrivals' own spread, and these are still rarely lost
    direct, copies = _rates(seed, 6.0, 6.0)
    assert copies <= 0.1
    assert direct <= 0.02


def test_each_beacons_replies_have_their_own_level_the_interrogations_one() -> None:
    weak = WeakArrivals()
    for _ in range(MIN_HISTORY + 2):
        # beacon 0's replies cross a short distance to the listener, beacon 1's a long one
        assert not weak.weak("R", 0, 25.0)
        assert not weak.weak("R", 1, 12.0)
        assert not weak.weak("I", 0, 20.0)
    assert not weak.weak("R", 1, 11.0)
    assert weak.weak("R", 0, 12.0)
    # the AUV's interrogations, whichever beacon they address, come from one source
    assert weak.weak("I", 1, 12.0)


def test_nothing_is_weak_before_the_history_nor_without_an_snr() -> None:
    weak = WeakArrivals()
    for _ in range(MIN_HISTORY - 1):
        weak.weak("I", 0, 20.0)
    assert not weak.weak("I", 0, -10.0)   # the history was one short
    assert weak.weak("I", 0, -10.0)
    assert not weak.weak("I", 0, math.nan)
