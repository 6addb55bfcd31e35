"""Gates that degrade gracefully: the measurement noise as measured, and re-anchoring.

The configured range noise (``timing_sigma_s``, ``range_sigma_m``) is what the
network should give.  A network that gives more — a beacon surveyed a metre or
two off, more detection jitter, a turnaround error the calibration has not
taken out yet — makes every innovation larger than its predicted spread, and a
fixed gate then refuses good fixes while the filter coasts on its prediction.

:class:`NoiseScale` measures the spread actually seen.  With three beacons or
more, the joint fix of each cycle (its ranges and the other beacons' recent
ones) over-determines the position: the χ² of its residuals per redundant
range, divided by that statistic's median (χ²₁: 0.455, χ²₂/2: 0.693, …),
times the scale in force, is one sample — the motion of the AUV plays no part
in it, so a turn is not taken for noise.  With two beacons there is no such
redundancy and the samples are the filter's innovations d² per row, taken
only while the AUV flies straight (the motion model is then right).  The scale
is the median of the last ``NOISE_WINDOW`` samples, never below 1 nor above
``NOISE_SCALE_MAX``.  Every range variance
the tracker uses (filter updates, the joint fix's consistency test) is
multiplied by it, so the gates widen with the residuals and narrow again when
they shrink.  A median ignores the outliers it must not learn from.

Re-anchoring: a run of ``reanchor_after`` refusals of fixes that the other
beacons' ranges confirm (a consistent joint fix) means the filter, not the
fixes, is off — a systematic error it was too sure about, or a manoeuvre it
missed.  Rather than coasting on, the tracker opens the filter's covariance
(:meth:`NoiseScale.reanchor_variance`) just enough for the latest fix to pass
the gate, and updates with it.
"""

from __future__ import annotations

from collections import deque
from statistics import median

#: straight-flight updates the measured noise scale is the median of
NOISE_WINDOW = 31
#: the scale's bounds (variance ratio)
NOISE_SCALE_MAX = 25.0


def mahalanobis2(dx: float, dy: float, a: float, b: float, d: float) -> float | None:
    """The Mahalanobis distance² of an offset (dx, dy) (m) under the 2×2
    covariance (a, b; b, d) (m²); None when that is not positive definite."""
    det = a * d - b * b
    if not det > 0.0:
        return None
    return (d * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det


def chi2_median_per_dof(dof: int) -> float:
    """Median of χ²/dof for ``dof`` degrees of freedom (Wilson–Hilferty beyond 2)."""
    if dof == 1:
        return 0.4549
    if dof == 2:
        return 0.6931
    return (1.0 - 2.0 / (9.0 * dof)) ** 3


class NoiseScale:
    """Measured scale of the range variances (module docstring)."""

    __slots__ = ("samples", "scale")

    def __init__(self) -> None:
        self.samples: deque[float] = deque(maxlen=NOISE_WINDOW)
        #: factor applied to every configured range variance (≥ 1)
        self.scale = 1.0

    def observe(self, chi2: float, dof: int) -> None:
        """Fold in a χ² with ``dof`` degrees of freedom computed with the range
        variances at the current scale: a joint fix's residuals (dof = ranges
        − 2) or a straight-flight innovation (dof = its rows)."""
        if dof < 1 or not chi2 >= 0.0:
            return
        self.samples.append(self.scale * chi2 / dof / chi2_median_per_dof(dof))
        if len(self.samples) >= NOISE_WINDOW // 3:
            self.scale = min(NOISE_SCALE_MAX, max(1.0, median(self.samples)))

    @staticmethod
    def reanchor_variance(d2: float, gate_chi2: float, fix_var: float) -> float:
        """Position variance (m², per axis) to add to the filter so that an
        innovation of d² (against a fix of variance ``fix_var`` per axis) comes
        within ``gate_chi2`` × 0.5: (d²/(gate/2) − 1) × (prediction + fix),
        bounded below by the fix's own variance."""
        return max(fix_var, (d2 / (0.5 * gate_chi2) - 1.0) * fix_var)
