"""Settings for the whole test suite.

Hypothesis's default per-example deadline (200 ms) and its "too slow" health
check are wall-clock bounds: on a loaded machine they fail tests that assert
nothing about time.  The tests assert behaviour; timing figures belong to
``tests/bench/``.  So every property test runs without a deadline and without
that check (a test may still set its own settings on top of these)."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

settings.register_profile("zarco", deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("zarco")
