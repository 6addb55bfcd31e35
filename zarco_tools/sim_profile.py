"""Where the simulator's time goes, and how fast it goes against another checkout.

:class:`Sampler` is a sampling profiler with the standard library only;
:func:`speed_side_by_side` times the same scenarios with two checkouts of the
code (e.g. this one and the commit before a change, from :func:`checkout`),
alternating them in one run.

A CPU-time timer signal interrupts the main thread every ``interval_s`` and
files the Python stack it interrupted under the first
category its stack matches, innermost frame first (numpy and the standard
library's helpers are skipped over, so their time counts for the code that
called them).  Sampling does not slow the profiled code down the way
``cProfile``'s per-call hooks do (those inflate the cost of small Python
functions several times over), so the shares are those of a normal run, to
within the sampling noise (√n of n samples).

Categories (:data:`CATEGORIES`), in the order they are tried for each frame:

* ``navstate``: building the published estimate (the estimator's ``state()``,
  its prediction to the message time, the covariance of the outputs, the
  geodetic position), i.e. the cost of NavState publication;
* ``estimator``: the navigation filter's own work (prediction, updates,
  history, fault monitors) and the navigation task;
* ``byte_path``: NMEA framing, checksums, parsing (our code and pynmea2), the
  device I/O loops, transports, the thruster protocol — both directions;
* ``sim_emitters``: the simulated devices formatting their sentences;
* ``sim_physics``: the vessel model, disturbances and the world's stepping;
* ``control``: guidance, control and allocation;
* ``tracking``: the AUV tracker (follow scenarios);
* ``bus_clock``: the message bus and the virtual-time loop's own code;
* ``asyncio``: the event loop, tasks, futures and the selector;
* ``other``: anything else (the report, the recorders, start-up).
"""

from __future__ import annotations

import json
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Any

#: (category, path fragments of its modules, function names or None for any)
_RULES: tuple[tuple[str, tuple[str, ...], frozenset[str] | None], ...] = (
    ("navstate", ("zarco_runtime/navigation/",),
     frozenset({"state", "_at", "_publish", "_validity", "to_geodetic", "nav_state"})),
    ("estimator", ("zarco_runtime/navigation/",), None),
    ("byte_path", ("drivers/nmea", "drivers/gps_parser", "drivers/compass_parser",
                   "drivers/buoy_parser", "drivers/transports", "drivers/thruster_driver",
                   "drivers/thruster_protocol", "pynmea2/"), None),
    ("sim_emitters", ("drivers/sim/sensors", "drivers/sim/acoustics", "drivers/sim/auv"),
     None),
    ("sim_physics", ("drivers/sim/",), None),
    ("control", ("zarco_runtime/control/", "zarco_runtime/guidance/",
                 "zarco_runtime/supervision/"), None),
    ("tracking", ("zarco_runtime/tracking/",), None),
    ("bus_clock", ("zarco_core/bus", "zarco_core/clock"), None),
    ("asyncio", ("/asyncio/", "/selectors.py", "/heapq"), None),
)
CATEGORIES = (*dict.fromkeys(r[0] for r in _RULES), "other")
#: frames that are skipped over (their time is their caller's)
_SKIP = ("/numpy/", "/math", "/contextlib", "/functools", "/typing", "/dataclasses",
         "/enum.py", "/re/", "/copy.py", "/collections/")


def _category(frame: FrameType | None) -> str:
    # a stack that builds the published estimate counts as ``navstate`` whatever
    # it calls (prediction, covariance); the other rules go by the innermost frame
    parts, funcs = _RULES[0][1], _RULES[0][2]
    assert funcs is not None
    f = frame
    while f is not None:
        code = f.f_code
        if code.co_name in funcs and any(p in code.co_filename for p in parts):
            return "navstate"
        f = f.f_back
    f = frame
    while f is not None:
        path = f.f_code.co_filename.replace("\\", "/")
        if not any(s in path for s in _SKIP):
            for cat, parts, _funcs in _RULES[1:]:
                if any(p in path for p in parts):
                    return cat
        f = f.f_back
    return "other"


class Sampler:
    """Samples the main thread's stack every ``interval_s`` of CPU time while active
    (``SIGPROF`` from ``setitimer(ITIMER_PROF)``: the handler runs in the main
    thread at the next bytecode, so time in a C call counts for its caller).

    ``with Sampler() as s: ...`` then ``s.shares()`` (fraction of samples per
    category) and ``s.samples``.  Unix only, main thread only."""

    def __init__(self, interval_s: float = 0.001) -> None:
        self.interval_s = interval_s
        self.counts: Counter[str] = Counter()
        self._old: Any = None

    @property
    def samples(self) -> int:
        return sum(self.counts.values())

    def _on_signal(self, _signum: int, frame: FrameType | None) -> None:
        self.counts[_category(frame)] += 1

    def __enter__(self) -> Sampler:
        self._old = signal.signal(signal.SIGPROF, self._on_signal)
        signal.setitimer(signal.ITIMER_PROF, self.interval_s, self.interval_s)
        return self

    def __exit__(self, *exc: Any) -> None:
        signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)
        signal.signal(signal.SIGPROF, self._old)

    def shares(self) -> dict[str, float]:
        """Fraction of the samples in each category (all of :data:`CATEGORIES`)."""
        n = max(1, self.samples)
        return {c: round(self.counts.get(c, 0) / n, 3) for c in CATEGORIES}


def profile_call(fn: Any, *args: Any, interval_s: float = 0.001) -> tuple[Any, dict[str, float],
                                                                          int, float]:
    """Run ``fn(*args)`` under a :class:`Sampler`: (result, shares, samples, wall s)."""
    w0 = time.perf_counter()
    with Sampler(interval_s) as s:
        out = fn(*args)
    return out, s.shares(), s.samples, time.perf_counter() - w0


# ------------------------------------------------ against another checkout
#: run in a fresh interpreter with a checkout first on sys.path: one scenario, its report
_RUNNER = r"""
import json, sys, time
root, scenario, seed = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path.insert(0, root)
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario
scn = load_scenario(scenario, sys.argv[4:], seed)
c0 = time.process_time()
rep = run_scenario(scn).report
rep["cpu_seconds"] = time.process_time() - c0
print(json.dumps({k: v for k, v in rep.items() if isinstance(v, (int, float, str))}))
"""


def run_report(root: Path, scenario: Path, overrides: list[str], seed: int = 1) -> dict[str, Any]:
    """Simulate ``scenario`` with the code of checkout ``root`` in a fresh interpreter;
    its report's scalar figures plus ``cpu_seconds`` (the process's CPU time)."""
    out = subprocess.run([sys.executable, "-c", _RUNNER, str(root), str(scenario), str(seed),
                          *overrides], capture_output=True, text=True, check=True)
    rep: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return rep


def speed_side_by_side(variants: dict[str, tuple[Path, Path, list[str]]], rounds: int = 3,
                       seed: int = 1, progress: Callable[[str], None] | None = None
                       ) -> dict[str, dict[str, Any]]:
    """Simulation speed of each variant (checkout root, scenario, overrides), ``rounds``
    times, the variants alternating within a round (their order reversed every other
    round), so that a machine shared with other work loads them alike.

    Per variant: ``speedup`` (simulated / wall seconds: the median, and every run in
    ``speedup_runs``) and ``cpu_speedup`` (simulated / CPU seconds of the process,
    less sensitive to other processes on the machine)."""
    res: dict[str, dict[str, list[float]]] = {k: {"wall": [], "cpu": []} for k in variants}
    for i in range(rounds):
        order = list(variants) if i % 2 == 0 else list(reversed(variants))
        for key in order:
            root, scenario, overrides = variants[key]
            rep = run_report(root, scenario, overrides, seed)
            res[key]["wall"].append(rep["speedup"])
            res[key]["cpu"].append(round(rep["sim_seconds"] / rep["cpu_seconds"], 1))
            if progress is not None:
                progress(f"  {key}: {rep['speedup']}× wall, {res[key]['cpu'][-1]}× CPU")
    return {k: {"speedup": statistics.median(v["wall"]), "speedup_runs": v["wall"],
                "cpu_speedup": statistics.median(v["cpu"]), "cpu_speedup_runs": v["cpu"]}
            for k, v in res.items()}


@contextmanager
def checkout(repo: Path, rev: str) -> Iterator[Path]:
    """A temporary checkout of ``rev`` (a git worktree beside nothing else), removed after."""
    tmp = Path(tempfile.mkdtemp(prefix="zarco-rev-"))
    path = tmp / "src"
    subprocess.run(["git", "-C", str(repo), "worktree", "add", "--detach", str(path), rev],
                   check=True, capture_output=True)
    try:
        yield path
    finally:
        subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(path)],
                       capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)
