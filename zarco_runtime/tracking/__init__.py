"""Passive AUV tracking from the buoy's acoustic feed (paper IV–V).

Pure, deterministic, synchronous code: no I/O, no asyncio, no clocks.  The
runtime feeds :class:`~zarco_runtime.tracking.tracker.AuvTracker` with
:class:`~zarco_core.auv_messages.AcousticEvent` messages and
publishes the :class:`~zarco_core.auv_messages.AuvTrack` it returns.

Modules, in data-flow order:

* :mod:`zarco_core.auv_messages` – AcousticEvent, BuoyStatus, AuvFix, AuvTrack,
  TrackFlags;
* :mod:`.params` – TrackerParams / the derived Network (also the config schema);
* :mod:`.layout` – beacons nearly on one line (the mirror side unobservable);
* :mod:`.timemap` – the acoustic UTC clock mapped onto the runtime clock;
* :mod:`.cycles` – I/R/I cycle assembly with gates and drop counters;
* :mod:`.fix` – ranges, emission time, motion-bias correction, circle and
  least-squares fixes;
* :mod:`.calibration` – the sound speed and the turnarounds' range biases,
  estimated online;
* :mod:`.assembly` – a cycle's fix: motion-corrected circles, mirror choice,
  the joint fix with the other beacons, range-only updates;
* :mod:`.gates` – the measured noise scale of the ranges, re-anchoring;
* :mod:`.acquire` – mirror vote, (re)initialisation of the filter;
* :mod:`.kalman` – constant-velocity Kalman filter with innovation gating;
* :mod:`.imm` – interacting multiple models (a quiet coordinated turn for
  lines and arcs, manoeuvring, turning at any rate, turning to port and to
  starboard);
* :mod:`.maneuver` – manoeuvre detection (IMM state, arcs, cross-course
  CUSUM) and the turn declaration;
* :mod:`.rls` – recursive least squares with forgetting on the line model;
* :mod:`.plan`, :mod:`.plan_geometry`, :mod:`.plan_flown`,
  :mod:`.plan_progress` – the AUV's a-priori plan: its legs and rounded
  corners (the AUV's guidance flown where no arc fits), which leg the AUV is
  on, its progress along the plan, leaving and re-joining it;
* :mod:`.tracker` – the glue, track flags, aging and lost declaration.
"""
