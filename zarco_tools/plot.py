"""Plots of a simulated mission (the paper's Figs. 4 and 5)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from zarco_core.paths import PathError, writable_file
from zarco_runtime.guidance.mission import Leg
from zarco_tools.sim_report import SETTLE_M, TrackLog, xtrack_series


def image_path(path: str | Path, what: str = "--plot") -> Path:
    """An image to write after a run, checked before it: a writable file
    (:func:`zarco_core.paths.writable_file`) whose extension names a type
    matplotlib writes (``.png``, ``.pdf``, ``.svg``, ...).  Raises PathError."""
    p = writable_file(path, what)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    types = FigureCanvasAgg.get_supported_filetypes()
    ext = p.suffix.lower().lstrip(".")
    if ext not in types:
        known = ", ".join(f".{t}" for t in sorted(types))
        raise PathError(path, f"not an image type that can be written: "
                        f"{('.' + ext) if ext else 'no extension'} (one of {known})", what)
    return p


def plot_lines(path: str | Path, log: TrackLog, legs: list[Leg], title: str,
               truth: bool = True) -> None:
    """Track over the planned lines, and cross-track error over time (``truth``:
    the simulator's true track; else the vessel's estimate, from a recording)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    along, d, leg_idx = xtrack_series(log, legs)
    t = np.asarray(log.t)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5),
                                   gridspec_kw={"width_ratios": [1, 1.4]})
    for leg in legs:
        ax1.plot([leg.e0, leg.e1], [leg.n0, leg.n1], "k--", lw=1, alpha=0.6)
    ax1.plot(log.y, log.x, "b-", lw=1.2, label="true track" if truth else "estimated track")
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


def plot_follow(path: str | Path, log: TrackLog, extra: dict, title: str,
                truth: bool = True) -> None:
    """Tracks, the AUV's estimated velocity and course (paper Figs. 7, 8), the
    ASV–AUV distance (Fig. 9) and the tracker's sound-speed estimate with its
    ±1σ (``truth``: the simulator's true tracks and sound speed; else the
    vessel's estimate and the AUV's filtered track, from a recording)."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from zarco_core.auv_messages import AuvFix, AuvTrack, TrackFlags

    auv = extra.get("auv_log", [])
    msgs = extra.get("auv_msgs", [])
    tracks = [m for m in msgs if isinstance(m, AuvTrack) and not m.lost
              and m.flags & TrackFlags.LINE_VALID]
    fixes = [m for m in msgs if isinstance(m, AuvFix) and m.accepted and not m.range_only]
    fig = plt.figure(figsize=(13, 12))
    grid = fig.add_gridspec(3, 2, height_ratios=(1.0, 1.0, 0.6))
    axs = [[fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])],
           [fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])]]
    ax = axs[0][0]
    what = "truth" if truth else "estimate"
    ax.plot([a[2] for a in auv], [a[1] for a in auv], "r-", lw=1.5, label=f"AUV ({what})")
    ax.plot(log.y, log.x, "b-", lw=1.0, label=f"ASV ({what})")
    ax.plot([f.y_m for f in fixes], [f.x_m for f in fixes], "k.", ms=2, alpha=0.4,
            label="passive fixes")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("tracks")
    tt = [m.t for m in tracks]
    ax = axs[0][1]
    ax.plot(tt, [m.vx_mps for m in tracks], "b-", label="v_x (north)")
    ax.plot(tt, [m.vy_mps for m in tracks], "r-", label="v_y (east)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("m/s")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("estimated AUV velocity (cf. paper Fig. 7)")
    ax = axs[1][0]
    # course in [0, 360): no wrap at the usual north/south survey courses
    ax.plot(tt, [math.degrees(m.psi_auv_rad) % 360.0 for m in tracks], "b.", ms=2,
            label="estimated")
    ax.plot([a[0] for a in auv], [math.degrees(a[3]) % 360.0 for a in auv],
            "k--", lw=0.8, label="true" if truth else "filtered track")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("course (deg)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("AUV course (cf. paper Fig. 8)")
    ax = axs[1][1]
    n = min(len(log.t), len(auv))
    ax.plot(log.t[:n], [math.hypot(log.x[i] - auv[i][1], log.y[i] - auv[i][2])
                        for i in range(n)], "b-")
    ax.axhline(3.0, color="k", lw=0.6, ls=":")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("distance (m)")
    ax.grid(True, alpha=0.3)
    ax.set_title("horizontal distance ASV–AUV (cf. paper Fig. 9)")
    _sound_speed_panel(fig.add_subplot(grid[2, :]), msgs, extra, truth)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _sound_speed_panel(ax: Any, msgs: list[Any], extra: dict, truth: bool) -> None:
    """The tracker's sound speed over time with its ±1σ band (and the
    simulator's true sound speed)."""
    import math

    from zarco_core.auv_messages import AuvTrack

    pts = [(m.t, m.sound_speed_mps, m.sound_speed_sigma_mps) for m in msgs
           if isinstance(m, AuvTrack) and math.isfinite(m.sound_speed_mps)]
    if pts:
        t = [p[0] for p in pts]
        c = [p[1] for p in pts]
        sg = [p[2] if math.isfinite(p[2]) else 0.0 for p in pts]
        ax.fill_between(t, [a - b for a, b in zip(c, sg, strict=True)],
                        [a + b for a, b in zip(c, sg, strict=True)], color="b", alpha=0.15,
                        label="±1σ")
        ax.plot(t, c, "b-", lw=1.0, label="estimated")
    acoustics = extra.get("acoustics")
    if truth and acoustics is not None:
        ax.axhline(float(acoustics.c), color="k", lw=0.8, ls="--", label="true")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("m/s")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("sound speed the tracker computes the ranges with")
