"""Benchmark: the follow campaign, run by the product tool (``zarco campaign
config/campaigns/follow.toml``).

    python tests/bench/campaign.py [--seed 1] [--n 60] [--jobs 2] [--quick]
                                   [--set KEY=VALUE ...] [--out DIR]
                                   [--scheduler tcp://HOST:8786]

Draws ``--n`` missions of the campaign of ``--seed`` (the families, ranges and
targets of the spec file: routes — lawnmowers, tight lawnmowers, random legs,
arcs, spirals —, the network, the AUV's speed up to 1.4 m/s, detections,
current, a plant that is not the runtime's model, and the calibration
errors: true sound speed ±1 % off the configured one, beacons surveyed up to
2 m off, turnarounds up to 2 ms off), runs them (``--jobs`` processes, or a
Dask cluster), writes ``DIR/results.jsonl`` as they arrive (a rerun resumes),
prints the progress and the tables on stderr and stdout, and ends with one
JSON line: the pass counts per target and family, the missions physics
exempts, the worst missions with the ``zarco sim`` command of each.
``--quick``: 12 missions.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_runtime.cli import main as zarco  # noqa: E402

SPEC = ROOT / "config" / "campaigns" / "follow.toml"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="campaign seed")
    ap.add_argument("--n", type=int, default=60, help="missions")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--quick", action="store_true", help="12 missions (a CI-sized check)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override applied to every mission (e.g. a runtime setting)")
    ap.add_argument("--out", default=None, help="output directory (default "
                    "out/campaign/follow-seedS)")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler's address")
    args = ap.parse_args()
    n = 12 if args.quick else args.n
    out = Path(args.out or ROOT / "out" / "campaign" / f"follow-seed{args.seed}")
    argv = ["campaign", str(SPEC), "--n", str(n), "--seed", str(args.seed), "--out", str(out)]
    argv += ["--scheduler", args.scheduler] if args.scheduler else ["--jobs", str(args.jobs)]
    for s in args.set:
        argv += ["--set", s]
    with contextlib.redirect_stdout(sys.stderr):  # the tables on stderr; the JSON alone on stdout
        rc = zarco(argv)
    if rc != 0:
        return rc
    s = json.loads((out / "summary.json").read_text())

    def counts(g: dict) -> dict:
        return {k: [c["passed"], c["applicable"], c["exempt"]] for k, c in
                {**g["checks"], "every_target": g["every_target"]}.items()
                if c["applicable"] or c["exempt"]}

    print(json.dumps({
        "bench": "campaign", "seed": args.seed, "missions": s["missions"], "set": args.set,
        "pass": counts(s["all"]),
        "pass_by_family": {f: counts(g) for f, g in s["by_family"].items()},
        "pass_by": {cat: {v: counts(g) for v, g in groups.items()}
                    for cat, groups in s["by"].items()},
        "manoeuvres": s["turns"], "exempt": s["exempt"], "worst": s["worst"],
        "spread": s["spread"], "time_above_4m_s": s.get("time_above_4m_s"),
        "factor_effects": {k: v[:3] for k, v in s.get("factor_effects", {}).items()},
        "cpu_s_per_mission": s["cpu_s_per_mission"], "wall_s": s["wall_s"],
        "results": str(out / "results.jsonl"),
    }, allow_nan=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
