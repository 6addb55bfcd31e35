"""Plots of a simulated mission (the paper's Figs. 4 and 5)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from zarco_runtime.guidance.mission import Leg
from zarco_runtime.sim_report import SETTLE_M, TrackLog, xtrack_series


def plot_lines(path: str | Path, log: TrackLog, legs: list[Leg], title: str) -> None:
    """Track over the planned lines, and cross-track error over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    along, d, leg_idx = xtrack_series(log, legs)
    t = np.asarray(log.t)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5),
                                   gridspec_kw={"width_ratios": [1, 1.4]})
    for leg in legs:
        ax1.plot([leg.e0, leg.e1], [leg.n0, leg.n1], "k--", lw=1, alpha=0.6)
    ax1.plot(log.y, log.x, "b-", lw=1.2, label="true track")
    ax1.plot(log.y[:1], log.x[:1], "go", label="start")
    ax1.set_xlabel("east (m)")
    ax1.set_ylabel("north (m)")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.grid(True, alpha=0.3)
    ax1.legend(loc="best", fontsize=8)
    ax1.set_title("track over the planned lines (cf. paper Fig. 4)")
    settled = along >= SETTLE_M
    ax2.plot(t, d, color="0.75", lw=0.8, label="cross-track (all)")
    dd = np.where(settled, d, np.nan)
    ax2.plot(t, dd, "b-", lw=1.0, label=f"cross-track, ≥ {SETTLE_M:.0f} m into the leg")
    for k in range(1, len(leg_idx)):
        if leg_idx[k] != leg_idx[k - 1]:
            ax2.axvline(t[k], color="k", lw=0.6, alpha=0.4)
    finite = np.abs(dd[np.isfinite(dd)])
    lim = max(0.1, float(np.percentile(finite, 99.5)) * 1.5) if finite.size else 1.0
    ax2.set_ylim(-lim, lim)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("cross-track error d (m, + starboard)")
    ax2.grid(True, alpha=0.3)
    ax2.legend(loc="upper right", fontsize=8)
    ax2.set_title("cross-track error (cf. paper Fig. 5); vertical lines: leg changes")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
