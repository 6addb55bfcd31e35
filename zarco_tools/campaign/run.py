"""Running a campaign's missions: one mission (:func:`run_mission`, what a
worker does), and the missions as they complete on a local process pool
(:func:`run_local`) or on a Dask distributed cluster (:func:`run_dask`).

A worker needs only the package: the spec travels as data (the base
scenario's TOML already read), and a mission is drawn from (spec, seed,
index) where it runs.
"""

from __future__ import annotations

import multiprocessing
import os
import socket
import time
from collections.abc import Generator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

from zarco_tools.campaign.draw import draw_mission, drawer
from zarco_tools.campaign.spec import CampaignSpec


def run_mission(spec: CampaignSpec, seed: int, index: int, sets: list[str]
                ) -> dict[str, Any]:
    """Draw and simulate mission ``index`` of campaign ``seed`` with the extra
    overrides ``sets``; its record (index, family, overrides, factors, figures,
    fails, exempt, severity; ``wall_s``, ``cpu_s`` and ``host`` say how it
    ran).  A crash is a result too: ``error`` and the ``crash`` check."""
    from zarco_tools.scenario import scenario_from_data
    from zarco_tools.simulation import run_scenario

    w0, c0 = time.perf_counter(), time.process_time()
    m = draw_mission(spec, seed, index)
    dr = drawer(spec.kind)
    rec: dict[str, Any] = {"index": index, "family": m.family,
                           "scenario_seed": m.scenario_seed, "overrides": m.overrides,
                           "factors": m.factors}
    try:
        scn = scenario_from_data(spec.scenario_data(), spec.scenario_file,
                                 [*m.overrides, *sets], m.scenario_seed)
        report = run_scenario(scn).report
    except Exception as exc:  # a crash is a mission's result
        rec.update({"figures": {}, "fails": {"crash": [repr(exc)]}, "exempt": {},
                    "severity": 99.0, "error": repr(exc)})
    else:
        j = dr.judge(spec, m.factors, report)
        rec.update({"figures": {k: report.get(k) for k in dr.figures}, "fails": j.fails,
                    "exempt": j.exempt, "severity": j.severity, "left_out": j.left_out})
        if j.turns_ok:
            rec["turns_ok"] = list(j.turns_ok)
    rec.update({"wall_s": round(time.perf_counter() - w0, 3),
                "cpu_s": round(time.process_time() - c0, 3),
                "host": f"{socket.gethostname()}:{os.getpid()}"})
    return rec


def noop(index: int) -> dict[str, Any]:
    """A task that does nothing: the scheduler's own cost per task, measured."""
    return {"index": index}


def run_local(spec: CampaignSpec, seed: int, indices: list[int], sets: list[str],
              jobs: int) -> Generator[dict[str, Any], None, None]:
    """The missions' records as they complete, on ``jobs`` local processes
    (fresh interpreters: spawned, not forked).  Closing the iterator early
    cancels what has not started."""
    # one thread per worker for numpy's BLAS, as Dask's workers have: the workers
    # are the parallelism (the spawned workers take this process's environment)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    ctx = multiprocessing.get_context("spawn")
    ex = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx)
    finished = False
    try:
        # keep a few missions queued per worker, not thousands of pickled specs
        todo = list(indices)
        running: set[Future[dict[str, Any]]] = set()
        while todo or running:
            while todo and len(running) < 2 * jobs:
                running.add(ex.submit(run_mission, spec, seed, todo.pop(0), sets))
            done, running = wait(running, return_when=FIRST_COMPLETED)
            for f in done:
                yield f.result()
        finished = True
    finally:
        if not finished:
            # interrupted: the missions under way are dropped (a resume reruns them)
            for proc in list(getattr(ex, "_processes", {}).values()):
                proc.terminate()
        ex.shutdown(wait=True, cancel_futures=True)


def run_dask(spec: CampaignSpec, seed: int, indices: list[int], sets: list[str],
             address: str) -> Generator[dict[str, Any], None, None]:
    """The missions' records as they complete, on the Dask distributed cluster
    whose scheduler is at ``address`` (``tcp://HOST:8786``).  The spec is sent
    to every worker once; a mission lost with its worker is run again."""
    from distributed import Client, as_completed

    with Client(address, timeout="30s") as client:  # type: ignore[no-untyped-call]
        spec_f = client.scatter(spec, broadcast=True)
        futs = [client.submit(run_mission, spec_f, seed, k, sets, pure=False, retries=2,
                              key=f"zarco-campaign-{spec.name}-{seed}-{k}-{os.getpid()}")
                for k in indices]
        try:
            for f in as_completed(futs):  # type: ignore[no-untyped-call]
                yield f.result()
                f.release()
        finally:
            client.cancel([f for f in futs if not f.done()])
