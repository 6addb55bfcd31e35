"""``zarco campaign compare A B``: two result sets of the same missions side by
side — a tuning judged on the missions it changed, not on new draws.

Missions are paired by index; a pair must be the same mission (the same
drawn overrides and scenario seed), else the comparison is refused (another
spec or seed).  Per check and per family: how many missions pass in A and in
B, and how many flipped (passed in A, missed in B: ``worse``; the other way:
``better``).  Per figure (those of :func:`zarco_tools.campaign.plots.figure_values`)
and per family: the paired difference B − A over the missions that have it
in both, its median and mean with a 95 % bootstrap interval of the mean.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from zarco_core.config import ConfigError
from zarco_tools.campaign.plots import figure_values
from zarco_tools.campaign.results import load_dir
from zarco_tools.campaign.tables import applies, in_every

#: bootstrap resamples of the mean difference (fixed seed: the same answer twice)
BOOTSTRAP = 2000


def _passes(rec: dict[str, Any], check: str) -> bool | None:
    """Whether ``rec`` passes ``check`` (None: not applicable, or exempt)."""
    if check == "every target":
        return not rec.get("fails") if in_every(rec) else None
    if not applies(check, rec) or check in rec.get("exempt", {}):
        return None
    return check not in rec.get("fails", {})


def _paired(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    va = [figure_values(r) for r in a]
    vb = [figure_values(r) for r in b]
    names = sorted({k for v in va for k in v} & {k for v in vb for k in v})
    rng = np.random.default_rng(0)
    for name in names:
        d = np.array([y[name] - x[name] for x, y in zip(va, vb, strict=True)
                      if name in x and name in y])
        if d.size == 0:
            continue
        boot = rng.choice(d, size=(BOOTSTRAP, d.size)).mean(axis=1)
        out[name] = {"n": int(d.size), "median": round(float(np.median(d)), 4),
                     "mean": round(float(d.mean()), 4),
                     "mean_ci95": [round(float(np.percentile(boot, 2.5)), 4),
                                   round(float(np.percentile(boot, 97.5)), 4)]}
    return out


def _checks(a: list[dict[str, Any]], b: list[dict[str, Any]], checks: list[str]
            ) -> dict[str, Any]:
    out = {}
    for c in [*checks, "every target"]:
        pa = [_passes(r, c) for r in a]
        pb = [_passes(r, c) for r in b]
        both = [(x, y) for x, y in zip(pa, pb, strict=True) if x is not None and y is not None]
        out[c] = {"n": len(both), "passed_a": sum(1 for x, _y in both if x),
                  "passed_b": sum(1 for _x, y in both if y),
                  "worse": sum(1 for x, y in both if x and not y),
                  "better": sum(1 for x, y in both if y and not x)}
    return out


def compare(path_a: str, path_b: str) -> dict[str, Any]:
    """The comparison of the module's docstring, as data."""
    ha, ra = load_dir(path_a)
    hb, rb = load_dir(path_b)
    common = sorted(set(ra) & set(rb))
    if not common:
        raise ConfigError(path_b, "results", f"no mission in common with {path_a}")
    for k in common:
        if (ra[k]["overrides"], ra[k]["scenario_seed"]) != (rb[k]["overrides"],
                                                            rb[k]["scenario_seed"]):
            raise ConfigError(path_b, f"mission {k}", f"is not the same mission as in "
                              f"{path_a} (another spec or seed): nothing to pair")
    checks = list(ha.get("checks") or hb.get("checks") or [])
    a = [ra[k] for k in common]
    b = [rb[k] for k in common]
    fams = sorted({r["family"] for r in a})
    return {
        "a": {"path": path_a, "sets": ha.get("sets"), "missions": len(ra)},
        "b": {"path": path_b, "sets": hb.get("sets"), "missions": len(rb)},
        "paired": len(common), "checks": checks,
        "all": {"checks": _checks(a, b, checks), "figures": _paired(a, b)},
        "by_family": {f: {"checks": _checks([x for x in a if x["family"] == f],
                                            [y for y in b if y["family"] == f], checks),
                          "figures": _paired([x for x in a if x["family"] == f],
                                             [y for y in b if y["family"] == f])}
                      for f in fams},
    }


def format_compare(c: dict[str, Any]) -> str:
    lines = [f"A: {c['a']['path']}  (--set {' '.join(c['a']['sets'] or []) or 'none'})",
             f"B: {c['b']['path']}  (--set {' '.join(c['b']['sets'] or []) or 'none'})",
             f"{c['paired']} missions paired", ""]
    groups = {"all": c["all"], **c["by_family"]}
    lines.append("missions within each target, A → B (worse: passed in A, missed in B):")
    lines.append(f"  {'':<14}{'check':<14}{'A':>6}{'B':>6}{'worse':>7}{'better':>7}{'n':>6}")
    for g, d in groups.items():
        for check, v in d["checks"].items():
            if v["n"]:
                lines.append(f"  {g:<14}{check:<14}{v['passed_a']:>6}{v['passed_b']:>6}"
                             f"{v['worse']:>7}{v['better']:>7}{v['n']:>6}")
    lines += ["", "paired differences B − A (median; mean [95 % interval]):"]
    for g, d in groups.items():
        for name, v in d["figures"].items():
            lo, hi = v["mean_ci95"]
            lines.append(f"  {g:<14}{name:<28}{v['median']:+9.3f}; {v['mean']:+9.3f} "
                         f"[{lo:+.3f}, {hi:+.3f}]  (n={v['n']})")
    return "\n".join(lines)


def write_compare(c: dict[str, Any], out: str | Path) -> None:
    import json

    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(c, indent=1, allow_nan=False) + "\n")
