"""Passive AUV tracking from the buoy's acoustic feed (paper IV–V).

Pure, deterministic, synchronous code: no I/O, no asyncio, no clocks.  The
runtime feeds :class:`~zarco_runtime.tracking.tracker.AuvTracker` with
:class:`~zarco_core.auv_messages.AcousticEvent` messages and
publishes the :class:`~zarco_core.auv_messages.AuvTrack` it returns.

Modules, in data-flow order:

* :mod:`.messages` – AcousticEvent, BuoyStatus, AuvFix, AuvTrack, TrackFlags;
* :mod:`.params` – TrackerParams / LblNetworkParams (also the config schema);
* :mod:`.cycles` – I/R/I cycle assembly with gates and drop counters;
* :mod:`.fix` – ranges, emission time, motion-bias correction, circle fix;
* :mod:`.kalman` – constant-velocity Kalman filter with innovation gating;
* :mod:`.imm` – interacting multiple models (straight, manoeuvring, turning);
* :mod:`.rls` – recursive least squares with forgetting on the line model;
* :mod:`.plan` – the AUV's a-priori plan: legs, corners, which leg it is on,
  leaving and re-joining it, the corners its prediction reaches;
* :mod:`.tracker` – the glue, track aging and lost declaration.
"""
