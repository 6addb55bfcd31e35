"""The pieces of the 1 Hz status snapshot the supervisor assembles: each device's
health summarised, and the counters."""

from __future__ import annotations

from zarco_core.messages import DeviceHealth, DeviceSummary

#: counters of a device that are not refusals (the rest are reasons a sentence was dropped)
NOT_REFUSALS = frozenset({
    "bytes", "sentences_ok", "status_ok", "reconnects", "open_failures", "bytes_discarded",
    "corrections_bytes", "corrections_dropped_bytes", "corrections_source_errors",
    "commands_sent", "watchdog_zero", "not_sent_disconnected", "write_errors",
    "nonfinite_commands", "rtcm_frames", "rtcm_dropped_bytes", "rtcm_bad_frames",
})


def device_summaries(devices: dict[str, DeviceHealth], now: float) -> dict[str, DeviceSummary]:
    """Each device's state, reason, age of its last good sentence (s), sentences
    accepted (``ok``) and refused (``bad``)."""
    out: dict[str, DeviceSummary] = {}
    for name, h in devices.items():
        c = h.counters
        ok = c.get("sentences_ok", 0) + c.get("status_ok", 0)
        bad = sum(v for k, v in c.items() if k not in NOT_REFUSALS)
        age = None if h.last_ok_t is None else round(now - h.last_ok_t, 3)
        out[name] = DeviceSummary(h.state.value, h.reason, age, ok, bad, dict(c))
    return out
