"""Cycle assembly: every gate, first arrival, drops counted with a reason."""

from __future__ import annotations

import math

import pytest

from zarco_core.auv_messages import AcousticEvent
from zarco_core.lbl import LblNetworkParams
from zarco_runtime.tracking.cycles import CycleAssembler
from zarco_runtime.tracking.params import Network

EPOCH = 1_780_308_000.0  # 2026-06-01T10:00:00Z
C = 1500.0
DEPTH = 10.0
#: a static AUV inside the default network
AUV = (150.0, 120.0, DEPTH)


def _net() -> Network:
    return Network.from_params(LblNetworkParams(), 0.003)


def _ev(utc: float, kind: str, beacon: int) -> AcousticEvent:
    return AcousticEvent(utc - EPOCH + 0.05, "buoy", utc, kind, beacon, 20.0)


def _beacon(net: Network, i: int) -> tuple[float, float, float]:
    return net.north[i], net.east[i], net.depth[i]


def _cycle_times(net: Network, i: int, t_ping: float,
                 auv: tuple[float, float, float] = AUV) -> tuple[float, float, float]:
    """Listener UTC of the interrogation and the reply of a ping to beacon index i
    at ``t_ping``, and the AUV's next ping time (static AUV, exact)."""
    lst = _beacon(net, net.listener)
    r_l = math.dist(auv, lst)
    r_i = math.dist(auv, _beacon(net, i))
    t_i = t_ping + r_l / C
    t_r = t_ping + r_i / C + net.tau[i] + net.d[i] / C
    return t_i, t_r, t_ping + 2 * r_i / C + net.tau[i] + net.delta


def _asm(net: Network, **kw: object) -> CycleAssembler:
    return CycleAssembler(net, DEPTH, 3000.0, **kw)  # type: ignore[arg-type]


def test_three_events_make_one_exact_cycle() -> None:
    net = _net()
    asm = _asm(net)
    t_i, t_r, t_next = _cycle_times(net, 1, EPOCH + 10.0)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    assert asm.push(_ev(t_i, "I", 2)) is None
    assert asm.push(_ev(t_r, "R", 2)) is None
    cyc = asm.push(_ev(t_i2, "I", 3))
    assert cyc is not None
    assert (cyc.index, cyc.beacon, cyc.next_beacon) == (1, 2, 3)
    assert (cyc.t_i, cyc.t_r, cyc.t_next) == (t_i, t_r, t_i2)
    assert not asm.dropped and not asm.cycles_dropped


def test_reply_gate_lower_and_upper_bounds() -> None:
    net = _net()
    i = 1
    for dt, counted in [(net.tau[i] - 0.004, "gate"),                      # before τ
                        (net.tau[i] + 2 * net.d[i] / C + 0.004, "gate"),  # beyond the detour
                        (net.tau[i] - 0.002, None),                       # inside the tolerance
                        (net.tau[i] + 2 * net.d[i] / C + 0.002, None)]:
        asm = _asm(net)
        asm.push(_ev(EPOCH, "I", 2))
        asm.push(_ev(EPOCH + dt, "R", 2))
        if counted:
            assert asm.dropped[counted] == 1, dt
        else:
            assert not asm.dropped, dt


def test_listener_beacon_reply_window_is_tau_only() -> None:
    net = _net()
    asm = _asm(net)
    tau = net.tau[net.listener]
    asm.push(_ev(EPOCH, "I", 1))
    asm.push(_ev(EPOCH + tau + 0.01, "R", 1))  # d = 0: nothing later than τ is physical
    assert asm.dropped["gate"] == 1


def test_reply_from_another_beacon_is_gated() -> None:
    net = _net()
    asm = _asm(net)
    t_i, t_r, _ = _cycle_times(net, 1, EPOCH)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_r, "R", 3))
    assert asm.dropped["gate"] == 1


def test_first_arrival_wins_and_late_copies_are_counted() -> None:
    net = _net()
    asm = _asm(net)
    t_i, t_r, t_next = _cycle_times(net, 1, EPOCH)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_i + 0.012, "I", 2))      # multipath copy of the interrogation
    asm.push(_ev(t_r, "R", 2))
    asm.push(_ev(t_r + 0.015, "R", 2))      # multipath copy of the reply
    cyc = asm.push(_ev(t_i2, "I", 3))
    assert cyc is not None and cyc.t_i == t_i and cyc.t_r == t_r
    assert asm.dropped["late_arrival"] == 2  # the copy of I and the copy of R
    assert not asm.cycles_dropped


def test_interrogation_too_soon_is_impossible_timing() -> None:
    net = _net()
    asm = _asm(net)
    t_i, t_r, t_next = _cycle_times(net, 1, EPOCH)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_r, "R", 2))
    # the AUV pings δ after hearing the reply, never sooner than τ + δ after t^I
    assert asm.push(_ev(t_r + 0.05, "I", 3)) is None
    assert asm.dropped["impossible_timing"] == 1
    assert asm.push(_ev(t_i2, "I", 3)) is not None  # the real one still closes it


def test_missed_closing_ping_without_prediction_uses_the_range_limit() -> None:
    net = _net()
    asm = CycleAssembler(net, DEPTH, 500.0)
    t_i, t_r, _ = _cycle_times(net, 1, EPOCH)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_r, "R", 2))
    late = t_i + net.tau[1] + net.delta + 2 * 500.0 / C + 0.01
    assert asm.push(_ev(late, "I", 3)) is None
    assert asm.cycles_dropped["missed_ping"] == 1


def test_missed_closing_ping_with_prediction() -> None:
    """With the filter's predicted range the next-but-one ping cannot close the
    cycle (a period one cycle too long would give a range hundreds of m off)."""
    net = _net()
    r_true = math.dist(AUV, _beacon(net, 1))
    asm = _asm(net, predictor=lambda idx, t: (math.dist(AUV, _beacon(net, idx)), 1.0))
    t_i, t_r, t_next = _cycle_times(net, 1, EPOCH)
    _t_i2, t_r2, t_next2 = _cycle_times(net, 2, t_next)  # I3 at _t_i2 is missed
    t_i3, _, _ = _cycle_times(net, 0, t_next2)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_r, "R", 2))
    asm.push(_ev(t_r2, "R", 3))  # reply to the missed interrogation: nothing to match
    assert asm.push(_ev(t_i3, "I", 1)) is None
    assert asm.cycles_dropped["missed_ping"] == 1
    assert asm.dropped["gate"] == 1
    # without the predictor the same events make a wrong cycle (r_i far too long)
    asm2 = _asm(net)
    asm2.push(_ev(t_i, "I", 2))
    asm2.push(_ev(t_r, "R", 2))
    asm2.push(_ev(t_r2, "R", 3))
    cyc = asm2.push(_ev(t_i3, "I", 1))
    assert cyc is not None
    r_wrong = 0.5 * C * (cyc.t_next - cyc.t_i - net.tau[1] - net.delta)
    assert r_wrong - r_true > 200.0


def test_sequence_check() -> None:
    net = _net()
    asm = _asm(net, sequence=[1, 2, 3])
    t_i, t_r, t_next = _cycle_times(net, 1, EPOCH)
    t_i2, _, _ = _cycle_times(net, 0, t_next)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_r, "R", 2))
    assert asm.push(_ev(t_i2, "I", 1)) is None  # 2 → 1, but the AUV goes 2 → 3
    assert asm.cycles_dropped["sequence"] == 1


def test_unanswered_interrogations_expire_as_no_reply() -> None:
    net = _net()
    asm = _asm(net)
    for k in range(5):
        asm.push(_ev(EPOCH + 2.0 * k, "I", 2))
    assert asm.dropped["no_reply"] == 4  # the last is still within its reply window


@pytest.mark.parametrize("bad,reason", [
    (AcousticEvent(0.0, "b", math.nan, "I", 1, 0.0), "garbage"),
    (AcousticEvent(0.0, "b", math.inf, "I", 1, 0.0), "garbage"),
    (AcousticEvent(0.0, "b", EPOCH, "Q", 1, 0.0), "garbage"),
    (AcousticEvent(0.0, "b", EPOCH, "I", "1", 0.0), "garbage"),  # type: ignore[arg-type]
    (AcousticEvent(0.0, "b", "soon", "I", 1, 0.0), "garbage"),  # type: ignore[arg-type]
    (AcousticEvent(0.0, "b", EPOCH, "I", 9, 0.0), "unknown_beacon"),
    (object(), "garbage"),
    (None, "garbage"),
])
def test_garbage_is_counted_never_raised(bad: object, reason: str) -> None:
    asm = _asm(_net())
    assert asm.push(bad) is None
    assert asm.dropped[reason] == 1


def test_duplicates_and_out_of_order() -> None:
    net = _net()
    asm = _asm(net)
    t_i, t_r, t_next = _cycle_times(net, 1, EPOCH)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    asm.push(_ev(t_i, "I", 2))
    asm.push(_ev(t_i, "I", 2))              # duplicate
    asm.push(_ev(t_r, "R", 2))
    asm.push(_ev(t_i + 0.2e-6, "I", 2))      # duplicate within 0.5 µs, and late
    asm.push(_ev(t_i - 1.0, "R", 3))         # out of order
    cyc = asm.push(_ev(t_i2, "I", 3))
    assert cyc is not None and cyc.t_i == t_i
    assert asm.dropped["duplicate"] == 2
    assert asm.dropped["out_of_order"] == 1
    assert asm.accepted == 3


def _true_range(net: Network, i: int) -> float:
    return math.dist(AUV, _beacon(net, i))


def test_a_missed_reply_still_gives_the_range_while_tracking() -> None:
    net = _net()
    asm = _asm(net, predictor=lambda i, t: (_true_range(net, i), 1.0))
    t_i, _t_r, t_next = _cycle_times(net, 1, EPOCH + 10.0)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    assert asm.push(_ev(t_i, "I", 2)) is None
    cyc = asm.push(_ev(t_i2, "I", 3))  # the reply between them was not heard
    assert cyc is not None and math.isnan(cyc.t_r)
    assert (cyc.index, cyc.t_i, cyc.t_next) == (1, t_i, t_i2)
    # the interval gives the exact range to beacon 2 (static AUV)
    r = 0.5 * C * (cyc.t_next - cyc.t_i - net.tau[1] - net.delta)
    assert r == pytest.approx(_true_range(net, 1), abs=1e-3)  # epoch-sized float times
    assert asm.cycles_no_reply == 1


def test_a_missed_reply_gives_nothing_without_a_prediction() -> None:
    net = _net()
    asm = _asm(net)
    t_i, _t_r, t_next = _cycle_times(net, 1, EPOCH + 10.0)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    asm.push(_ev(t_i, "I", 2))
    assert asm.push(_ev(t_i2, "I", 3)) is None


def test_no_reply_cycle_refused_off_the_predicted_period() -> None:
    net = _net()
    # the prediction puts the AUV 60 m further from beacon 2 than it is
    asm = _asm(net, predictor=lambda i, t: (_true_range(net, i) + 60.0, 1.0))
    t_i, _t_r, t_next = _cycle_times(net, 1, EPOCH + 10.0)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    asm.push(_ev(t_i, "I", 2))
    assert asm.push(_ev(t_i2, "I", 3)) is None


def test_a_multipath_copy_of_an_interrogation_is_not_the_next_ping() -> None:
    net = _net()
    asm = _asm(net, predictor=lambda i, t: (_true_range(net, i), 1.0))
    t_i, _t_r, t_next = _cycle_times(net, 1, EPOCH + 10.0)
    t_i2, _, _ = _cycle_times(net, 2, t_next)
    asm.push(_ev(t_i, "I", 2))
    assert asm.push(_ev(t_i + 0.012, "I", 2)) is None  # late copy, 12 ms
    cyc = asm.push(_ev(t_i2, "I", 3))
    assert cyc is not None and cyc.t_i == t_i  # measured from the direct arrival


def _snr_ev(utc: float, kind: str, beacon: int, snr_db: float) -> AcousticEvent:
    return AcousticEvent(utc - EPOCH + 0.05, "buoy", utc, kind, beacon, snr_db)


def test_a_weak_late_copy_alone_does_not_close_the_cycle() -> None:
    """The closing interrogation's direct arrival is missed and its multipath
    copy, 12 ms late and 7 dB down, is all the listener hears: the copy is
    dropped as weak instead of closing the cycle 9 m long."""
    net = _net()
    asm = _asm(net)
    t = EPOCH
    order = [1, 2, 0]
    for k in range(12):
        i = order[k % 3]
        t_i, t_r, t_next = _cycle_times(net, i, t)
        asm.push(_snr_ev(t_i, "I", net.ids[i], 20.0 + 0.5 * (k % 3)))
        asm.push(_snr_ev(t_r, "R", net.ids[i], 15.0 + 0.5 * (k % 2)))
        t = t_next
    i = order[12 % 3]
    t_i, t_r, t_next = _cycle_times(net, i, t)
    asm.push(_snr_ev(t_i, "I", net.ids[i], 20.0))
    asm.push(_snr_ev(t_r, "R", net.ids[i], 15.0))
    nxt = order[13 % 3]
    t_i2, _, _ = _cycle_times(net, nxt, t_next)
    assert asm.push(_snr_ev(t_i2 + 0.012, "I", net.ids[nxt], 13.0)) is None
    assert asm.dropped["weak"] == 1
    # the same copy as strong as the direct arrivals would have closed it, late
    strong = _asm(net)
    strong.push(_snr_ev(t_i, "I", net.ids[i], 20.0))
    strong.push(_snr_ev(t_r, "R", net.ids[i], 15.0))
    cyc = strong.push(_snr_ev(t_i2 + 0.012, "I", net.ids[nxt], 20.0))
    assert cyc is not None and cyc.t_next == t_i2 + 0.012
