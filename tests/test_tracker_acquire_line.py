"""Acquisition over beacons in a line: every baseline has the same mirror, so
the other beacons cannot resolve it and the prior must (as for one baseline);
over beacons out of line the prior is never used."""

from __future__ import annotations

import statistics

import pytest

from tests.tracker_rig import run

#: three beacons within 2 m of one line 420 m long (NED m, depth m)
IN_LINE = [[0.0, 0.0, 30.0], [120.0, 201.0, 40.0], [240.0, 398.5, 25.0]]
#: three beacons around the same area
TRIANGLE = [[0.0, 0.0, 30.0], [260.0, 120.0, 40.0], [40.0, 380.0, 25.0]]


def _followed(beacons: list[list[float]], prior: list[float], seed: int
              ) -> tuple[float | None, float, int]:
    """An AUV waiting 40 s, then a leg along the line, 70 m to its east: when
    the track was first initialised (s), the median position error (m) from
    then on, and the ``fix.mirror_prior`` count."""
    wps = [[80.0, 190.0], [200.0, 390.0]]  # 70-75 m east of the line, both ends
    r = run(wps, 160.0, seed=seed, lbl={"beacons": beacons, "listener_beacon": 1,
                                          "p_false": 0.03, "p_miss": 0.13},
            speed_mps=1.2, depth_m=20.0, start_delay_s=40.0, trk={"prior": prior})
    acq = r.acquired_s
    errs = [r.position_error(s) for s in r.after(acq if acq is not None else 1e9)]
    return (acq, statistics.median(errs) if errs else float("inf"),
            r.tracker.counters().get("fix.mirror_prior", 0))


@pytest.mark.parametrize("seed", [3, 11])
def test_beacons_in_a_line_take_the_prior_side(seed: int) -> None:
    # the prior 8 m off the AUV's start, on its side of the line (the mirror
    # is ~150 m away on the other)
    acq, err, used = _followed(IN_LINE, [74.0, 195.0], seed)
    assert acq is not None and acq <= 60.0
    assert err < 2.0
    assert used >= 1


def test_beacons_out_of_line_never_use_the_prior() -> None:
    # the prior 6 m from the start's mirror across the baseline of beacons 1
    # and 2 (220.6, 309.4): taken for a fix on it, the mirror would be chosen
    acq, err, used = _followed(TRIANGLE, [215.0, 305.0], 5)
    assert acq is not None and acq <= 60.0
    assert err < 2.0
    assert used == 0
