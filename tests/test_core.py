"""Virtual clock, bus back-pressure and the task group's shutdown."""

from __future__ import annotations

import asyncio

import pytest

from zarco_core.bus import Bus
from zarco_core.clock import Clock, DeadlockError, run_virtual
from zarco_core.messages import Fault


def test_virtual_clock_runs_an_hour_instantly_and_in_order() -> None:
    order: list[tuple[float, str]] = []

    async def ticker(name: str, period: float, clock: Clock) -> None:
        k = 0
        while True:
            k += 1
            await clock.sleep_until(k * period)
            order.append((clock.now(), name))

    async def main() -> float:
        clock = Clock(utc_offset_s=1.7e9)
        with pytest.raises(TimeoutError):
            async with asyncio.timeout(3600.0):
                async with asyncio.TaskGroup() as tg:
                    tg.create_task(ticker("a", 0.5, clock))
                    tg.create_task(ticker("b", 0.3, clock))
        assert clock.utc(10.0) == pytest.approx(1.7e9 + 10.0)
        return clock.now()

    import time

    w = time.monotonic()
    end = run_virtual(main())
    assert end == pytest.approx(3600.0)
    assert time.monotonic() - w < end  # the virtual hour was not waited for
    times = [t for t, _ in order]
    assert times == sorted(times)
    assert sum(1 for _, n in order if n == "a") == 7199


def test_virtual_deadlock_is_detected() -> None:
    async def main() -> None:
        await asyncio.get_running_loop().create_future()

    with pytest.raises(DeadlockError):
        run_virtual(main())


def test_slow_subscriber_drops_oldest_and_never_blocks() -> None:
    bus = Bus()
    slow = bus.subscribe(Fault, maxlen=3)
    latest = bus.latest(Fault)
    for i in range(10):
        bus.publish(Fault(float(i), "x", str(i)))
    assert slow.dropped == 7
    assert [m.t for m in slow.drain()] == [7.0, 8.0, 9.0]
    assert latest.value is not None and latest.value.t == 9.0


def test_multi_type_subscription_keeps_order() -> None:
    from zarco_core.messages import RateOfTurn

    bus = Bus()
    sub = bus.subscribe(Fault, RateOfTurn)
    bus.publish(Fault(1.0, "a", "x"))
    bus.publish(RateOfTurn(2.0, "c", 0.1))
    bus.publish(Fault(3.0, "a", "y"))
    assert [type(m).__name__ for m in sub.drain()] == ["Fault", "RateOfTurn", "Fault"]
