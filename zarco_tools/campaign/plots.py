"""Which drawn factor breaks which target: the figures plotted against every
numeric factor drawn, and each check's miss rate among the missions in the
top third of a factor's drawn values against the bottom third.

``factor_effects`` is numbers only (the text summary prints it); the plots
need matplotlib (the ``sim`` extra).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from zarco_tools.campaign.tables import applies
from zarco_tools.follow_distance import PHASES

#: figures plotted: name, the check it belongs to, its target's name (those
#: present are drawn)
FIGURES = (
    ("distance_median_m", "median", "distance_median_m"),
    ("distance_p95_m", "p95", "distance_p95_m"),
    ("turn peak (m)", "turn", "turn_max_m"), ("turn recovery (s)", "turn", "turn_recovery_s"),
    ("uturn peak (m)", "uturn", "uturn_max_m"),
    ("uturn recovery (s)", "uturn", "uturn_recovery_s"),
    ("arc peak (m)", "arc", "arc_max_m"), ("lost_max_s", "lost", "lost_max_s"),
    ("sound_speed_error_max_pct", "sound_speed", "sound_speed_error_pct"),
    ("xtrack_rms_m", "rms", "xtrack_rms_m"), ("xtrack_p95_m", "p95", "xtrack_p95_m"),
    ("hold_distance_p95_m", "p95", "hold_p95_m"), ("hold_distance_max_m", "max", "hold_max_m"),
)
#: factors plotted at most (those that move the miss rates most)
MAX_FACTORS = 10
#: where an unrecovered manoeuvre is drawn (s)
UNRECOVERED_S = 150.0


def figure_values(rec: dict[str, Any]) -> dict[str, float]:
    """The plotted figures of one mission (the worst manoeuvre of each kind)."""
    fig = rec.get("figures") or {}
    out: dict[str, float] = {}
    for name, _check, _target in FIGURES:
        v = fig.get(name)
        if isinstance(v, (int, float)) and math.isfinite(v):
            out[name] = float(v)
    for t in fig.get("turns") or []:
        k = t.get("kind")
        peak, rec_s = t.get("distance_max_m"), t.get("recovery_s")
        if peak is not None:
            out[f"{k} peak (m)"] = max(out.get(f"{k} peak (m)", 0.0), float(peak))
        if k != "arc":
            r = UNRECOVERED_S if rec_s is None else min(float(rec_s), UNRECOVERED_S)
            out[f"{k} recovery (s)"] = max(out.get(f"{k} recovery (s)", 0.0), r)
    return out


def numeric_factors(records: list[dict[str, Any]]) -> list[str]:
    """The factors drawn as numbers that vary across the missions."""
    names: dict[str, set[float]] = {}
    for r in records:
        for k, v in r["factors"].items():
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                names.setdefault(k, set()).add(float(v))
    return [k for k, vals in names.items() if len(vals) > 2]


def factor_effects(records: list[dict[str, Any]], checks: list[str]
                   ) -> dict[str, list[dict[str, Any]]]:
    """Per check that some mission failed: every numeric factor with the miss
    rate among the applicable missions in its top third and bottom third of
    drawn values, largest difference first."""
    out: dict[str, list[dict[str, Any]]] = {}
    facs = numeric_factors(records)
    for check in checks:
        app = [r for r in records if applies(check, r) and check not in r.get("exempt", {})]
        if not any(check in r.get("fails", {}) for r in app) or len(app) < 6:
            continue
        rows: list[dict[str, Any]] = []
        for f in facs:
            sel = [r for r in app if isinstance(r["factors"].get(f), (int, float))]
            if len(sel) < 6:
                continue
            vals = np.array([float(r["factors"][f]) for r in sel])
            miss = np.array([check in r.get("fails", {}) for r in sel], dtype=float)
            lo, hi = np.percentile(vals, [100 / 3, 200 / 3])
            low, high = miss[vals <= lo], miss[vals >= hi]
            if low.size == 0 or high.size == 0:
                continue
            rows.append({"factor": f, "miss_low": round(float(low.mean()), 3),
                         "miss_high": round(float(high.mean()), 3),
                         "difference": round(float(high.mean() - low.mean()), 3),
                         "low_below": round(float(lo), 3), "high_above": round(float(hi), 3)})
        rows.sort(key=lambda r: -abs(float(r["difference"])))
        out[check] = rows
    return out


def format_effects(effects: dict[str, list[dict[str, Any]]], top: int = 3) -> str:
    lines = ["which factor breaks which target (miss rate in the top third of the factor's "
             "values vs the bottom third):"]
    for check, rows in effects.items():
        cells = [f"{r['factor']} {100 * r['miss_high']:.0f} % vs {100 * r['miss_low']:.0f} %"
                 for r in rows[:top]]
        lines.append(f"  {check:<12} " + ("; ".join(cells) or "—"))
    return "\n".join(lines)


def plot_campaign(out_dir: Path, records: list[dict[str, Any]], checks: list[str],
                  title: str, targets: dict[str, float] | None = None) -> list[str]:
    """``figures.png`` (every plotted figure against the drawn factors that move
    the miss rates most; a mission that missed the figure's target in red, its
    target dashed), ``breaks.png`` (the miss-rate differences as a map) and,
    for follow campaigns, ``above.png`` (:func:`plot_time_above`); returns the
    files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eff = factor_effects(records, checks)
    weight: dict[str, float] = {}
    for effs in eff.values():
        for e in effs:
            weight[e["factor"]] = max(weight.get(e["factor"], 0.0), abs(e["difference"]))
    facs = sorted(numeric_factors(records), key=lambda f: -weight.get(f, 0.0))[:MAX_FACTORS]
    vals = [figure_values(r) for r in records]
    figs = [(n, c, t) for n, c, t in FIGURES if any(n in v for v in vals)]
    written: list[str] = []
    if facs and figs:
        fig, axs = plt.subplots(len(figs), len(facs), squeeze=False,
                                figsize=(2.1 * len(facs), 1.8 * len(figs)))
        for i, (name, check, target) in enumerate(figs):
            for j, f in enumerate(facs):
                ax = axs[i][j]
                pts = [(r["factors"].get(f), v[name], check in r.get("fails", {}),
                        check in r.get("exempt", {}))
                       for r, v in zip(records, vals, strict=True)
                       if name in v and isinstance(r["factors"].get(f), (int, float))]
                if pts:
                    x = [p[0] for p in pts]
                    y = [p[1] for p in pts]
                    c = ["tab:red" if p[2] else "0.6" if p[3] else "tab:blue" for p in pts]
                    ax.scatter(x, y, s=6, c=c)
                if targets and target in targets:
                    ax.axhline(targets[target], color="k", lw=0.6, ls="--")
                ax.tick_params(labelsize=6)
                if i == len(figs) - 1:
                    ax.set_xlabel(f, fontsize=7)
                if j == 0:
                    ax.set_ylabel(name, fontsize=7)
        fig.suptitle(f"{title}: figures against the drawn factors (red: the mission missed "
                     "that target; grey: exempt; dashed: the target)", fontsize=9)
        fig.tight_layout()
        p = out_dir / "figures.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        written.append(str(p))
    facs = numeric_factors(records)
    if eff and facs:
        names = list(eff)
        m = np.full((len(names), len(facs)), np.nan)
        for i, check in enumerate(names):
            for e in eff[check]:
                m[i, facs.index(e["factor"])] = e["difference"]
        fig, ax = plt.subplots(figsize=(1.0 + 0.7 * len(facs), 1.2 + 0.5 * len(names)))
        im = ax.imshow(m, cmap="RdBu_r", vmin=-1.0, vmax=1.0, aspect="auto")
        ax.set_xticks(range(len(facs)), facs, rotation=60, ha="right", fontsize=7)
        ax.set_yticks(range(len(names)), names, fontsize=8)
        for i in range(len(names)):
            for j in range(len(facs)):
                if math.isfinite(m[i, j]):
                    ax.text(j, i, f"{m[i, j]:+.2f}", ha="center", va="center", fontsize=6)
        fig.colorbar(im, ax=ax, label="miss rate: top third − bottom third")
        ax.set_title(f"{title}: which factor breaks which target", fontsize=9)
        fig.tight_layout()
        p = out_dir / "breaks.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        written.append(str(p))
    above = plot_time_above(out_dir, records, title)
    if above is not None:
        written.append(above)
    return written


def plot_time_above(out_dir: Path, records: list[dict[str, Any]], title: str) -> str | None:
    """``above.png``: per family (and all), the seconds further than 4 m from
    the AUV summed over its missions, stacked by phase, beside the budget a
    p95 within 4 m allows them (a black tick); None when no mission has the
    figure."""
    import matplotlib.pyplot as plt

    rows = [(r["family"], a) for r in records
            if (a := (r.get("figures") or {}).get("time_above_4m_s"))]
    if not rows:
        return None
    groups = sorted({f for f, _a in rows})
    names = [*groups, "all"] if len(groups) > 1 else groups
    sums = {n: {k: sum(float(a.get(k, 0.0)) for f, a in rows if n in ("all", f))
                for k in (*PHASES, "budget")} for n in names}
    fig, ax = plt.subplots(figsize=(9.0, 1.0 + 0.45 * len(names)))
    left = np.zeros(len(names))
    for ph in PHASES:
        w = np.array([sums[n][ph] for n in names])
        ax.barh(names, w, left=left, label=ph.replace("_", "-"))
        left += w
    ax.scatter([sums[n]["budget"] for n in names], names, marker="|", s=300, c="k",
               label="budget (5 %)", zorder=3)
    ax.invert_yaxis()
    ax.set_xlabel("s further than 4 m from the AUV, summed over the missions", fontsize=8)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    ax.set_title(f"{title}: where the whole-time p95 goes", fontsize=9)
    fig.tight_layout()
    p = out_dir / "above.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    return str(p)
