"""Benchmark: how fast ``zarco campaign`` gets through missions, on the local
process pool and on a Dask LocalCluster of the same size, and what the
scheduler costs per mission.

    python tests/bench/campaign_speed.py [--jobs 2] [--n 6] [--duration 120]
                                         [--runs 2] [--noop 200]

Per run and executor: the same ``--n`` missions of the follow campaign cut to
``--duration`` simulated seconds.  Missions per CPU-minute: the missions over
all the CPU time the campaign took — the workers' (start-up, imports,
unpickling, the missions) and this process's (dispatch, and with Dask the
scheduler, which a LocalCluster runs here) — so a shared, loaded machine does
not count its waiting; the missions' own CPU time; the overhead per mission
(that total less the missions' own CPU, over the missions); and, for the
record, missions per wall-minute per worker.  Then ``--noop`` tasks that do
nothing, through each executor: the scheduler's round trip per task alone
(median and p90 over the runs).  Progress on stderr; one JSON line at the
end.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from zarco_tools.campaign.run import noop, run_dask, run_local  # noqa: E402
from zarco_tools.campaign.spec import load_spec  # noqa: E402

SPEC = ROOT / "config" / "campaigns" / "follow.toml"


def _figures(recs: list[dict[str, Any]], wall: float, cpu_total: float, jobs: int
             ) -> dict[str, float]:
    own = sum(r["cpu_s"] for r in recs)
    n = len(recs)
    return {"missions": n, "wall_s": round(wall, 2), "cpu_s": round(cpu_total, 2),
            "missions_per_cpu_min": round(n / (cpu_total / 60.0), 3),
            "mission_cpu_s_mean": round(own / n, 3),
            "overhead_cpu_per_mission_s": round((cpu_total - own) / n, 3),
            "missions_per_worker_wall_min": round(n / (wall * jobs / 60.0), 3)}


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _workers_cpu(address: str) -> float:
    from distributed import Client

    with Client(address) as c:
        return float(sum(c.run(time.process_time).values()))


def _noop_pool(n: int, jobs: int) -> float:
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as ex:
        list(ex.map(noop, range(jobs)))  # started
        t0 = time.perf_counter()
        for f in as_completed([ex.submit(noop, k) for k in range(n)]):
            f.result()
        return (time.perf_counter() - t0) / n


def _noop_dask(n: int, address: str) -> float:
    from distributed import Client
    from distributed import as_completed as dask_completed

    with Client(address) as c:
        t0 = time.perf_counter()
        for f in dask_completed([c.submit(noop, k, pure=False) for k in range(n)]):
            f.result()
        return (time.perf_counter() - t0) / n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--n", type=int, default=6, help="missions per run")
    ap.add_argument("--duration", type=float, default=120.0, help="simulated s per mission")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--noop", type=int, default=200, help="no-op tasks per run")
    args = ap.parse_args()
    from distributed import LocalCluster

    spec = load_spec(SPEC)
    sets = [f"scenario.max_duration_s={args.duration}"]
    idx = list(range(args.n))
    out: dict[str, list[dict[str, float]]] = {"pool": [], "dask": []}
    noops: dict[str, list[float]] = {"pool": [], "dask": []}
    with LocalCluster(n_workers=args.jobs, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        for run in range(args.runs):
            for name in ("pool", "dask"):
                addr = cluster.scheduler_address
                w_cpu = _children_cpu() if name == "pool" else _workers_cpu(addr)
                c0, t0 = time.process_time(), time.perf_counter()
                it = (run_local(spec, 1, idx, sets, args.jobs) if name == "pool"
                      else run_dask(spec, 1, idx, sets, addr))
                recs = list(it)
                wall, here = time.perf_counter() - t0, time.process_time() - c0
                w_cpu = (_children_cpu() if name == "pool" else _workers_cpu(addr)) - w_cpu
                fig = _figures(recs, wall, w_cpu + here, args.jobs)
                out[name].append(fig)
                noops[name].append(_noop_pool(args.noop, args.jobs) if name == "pool"
                                   else _noop_dask(args.noop, cluster.scheduler_address))
                print(f"run {run + 1}/{args.runs} {name}: {json.dumps(fig)}; no-op task "
                      f"{1000 * noops[name][-1]:.2f} ms", file=sys.stderr, flush=True)

    def agg(name: str) -> dict[str, Any]:
        rows = out[name]
        keys = ("missions_per_cpu_min", "mission_cpu_s_mean", "overhead_cpu_per_mission_s",
                "missions_per_worker_wall_min")
        nn = sorted(noops[name])
        return {**{k: round(statistics.median(r[k] for r in rows), 3) for k in keys},
                "noop_task_ms_p50": round(1000 * statistics.median(nn), 3),
                "noop_task_ms_p90": round(1000 * nn[min(len(nn) - 1,
                                                        int(0.9 * len(nn)))], 3),
                "runs": rows}

    pool, dask = agg("pool"), agg("dask")
    print(json.dumps({"bench": "campaign_speed", "jobs": args.jobs, "missions": args.n,
                      "duration_s": args.duration, "pool": pool, "dask": dask,
                      "dask_over_pool_throughput": round(dask["missions_per_cpu_min"]
                                                         / pool["missions_per_cpu_min"], 3)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
