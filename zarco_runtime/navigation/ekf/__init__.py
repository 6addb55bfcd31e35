"""Navigation EKF: RTK GPS, compass, true heading, gyro and the thruster commands → NavState.

:class:`EkfNavigator` is a drop-in replacement for
:class:`~zarco_runtime.navigation.simple.SimpleNavigator` (same ``on_fix``,
``on_velocity``, ``on_heading``, ``on_rate``, ``has_gyro``, ``state``), plus
``on_gst``, ``on_command`` (the thruster commands, with the vessel model given
by :meth:`EkfNavigator.set_vessel`) and :meth:`EkfNavigator.status`.

Its parts, one module each:

* :mod:`.layout`: the state (16: position, speed through the water, heading,
  yaw rate, gyro and compass biases, current, GPS offset, thrust scale,
  thruster mismatch and misalignment), a measurement, the filter state the
  history copies, the counters;
* :mod:`.noise`: sensor noise, GPS offset model and gates from the settings;
* :mod:`.model`: the process model (the vessel model driven by the thruster
  commands) and the prediction;
* :mod:`.updates`: the update algebra (scalar, 2-D, small inverses) and the
  gate bookkeeping; :mod:`.gps` and :mod:`.heading`: each sensor's updates,
  initialisation and fault handling; :mod:`.fusion`: one time of validity's
  measurements (prediction, joint update);
* :mod:`.history`: times of validity, the history and the replay of late
  measurements;
* :mod:`.monitors`: heading-source fault detectors, validity of the estimate;
* :mod:`.navigator`: messages in, NavState and :class:`EkfStatus` out.

EKF rather than UKF
-------------------
The nonlinearities are mild and smooth (rotations by ψ in the kinematics and
the velocity measurement, the products u·r, |u|·u in the model), all
measurements but the velocity are linear, and the state is observed at
10–20 Hz, so the linearisation error between updates is tiny.  A UKF needs
2n+1 = 33 sigma points per predict and per update, some twenty times the
arithmetic of the EKF.  Heading wrap-around is handled explicitly (innovations
wrapped to (−π, π]), as a UKF would need too.

Representation and cost
-----------------------
The mean is a list of Python floats (scalar ``math`` for the nonlinear parts);
the 16×16 covariance is a numpy array, and every product is one numpy call on
preallocated Jacobians (``F``, the velocity and output rows are filled in place
through precomputed flat indices, never allocated per step).  P is
symmetrised every few predictions.  Measurements that share a time of validity
share one prediction and one history snapshot.
"""

from zarco_runtime.navigation.ekf.layout import KIND_NAMES, STATE_NAMES
from zarco_runtime.navigation.ekf.navigator import EkfNavigator, EkfStatus

__all__ = ["KIND_NAMES", "STATE_NAMES", "EkfNavigator", "EkfStatus"]
