"""Benchmark: the NMEA byte path, pynmea2 on it (old) against our own split (new).

    python tests/bench/parsers.py [--rounds 5] [--seeds 1 2] [--base REV] [--no-sim]

"Old" is the five parser modules (``drivers/nmea.py``, ``gps_parser.py``,
``compass_parser.py``, ``buoy_parser.py``, ``thruster_protocol.py``) of
``--base``: by default the last commit whose ``drivers/nmea.py`` still
imported pynmea2.  Everything else (messages, the simulator, the EKF, the
runtime) is this tree's, so the ratios are the parsers' alone.  Per-type
timings run old and new in this one process, in alternating batches, so
that both see the same load; the simulations run in separate processes
(this tree, and a copy of it with the old parser modules), alternately, on
the same seeds.  Figures are medians.

Measured:

* per sentence type, sentences per second through the driver entry point
  (``parse_gps`` / ``parse_compass`` / ``parse_buoy`` / ``parse_pzths`` /
  ``parse_pzthr``), CPU time per call; GLL and GNS were not
  read before (``unsupported``), so their old figure is the cost of the
  refusal;
* framing (``NmeaFramer.feed`` on one simulated GPS epoch) and sentence
  formatting with its checksum (``format_sentence``, used by the simulated
  devices);
* the rectangle scenario with the EKF (``runtime.navigation.estimator=ekf``):
  simulated seconds per wall second (``speedup``, the simulator's figure)
  and per CPU second of the simulating process (``speedup_cpu``, less
  sensitive to other jobs on a shared machine), per seed; and the share of
  each run's time spent parsing, framing and formatting sentences (entry
  points wrapped with timers), which says what the parsers can still give.

Per-type timings use CPU time (``time.process_time``) for the same reason.

Progress goes to stderr; the last line on stdout is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
PARSER_FILES = ["drivers/nmea.py", "drivers/gps_parser.py", "drivers/compass_parser.py",
                "drivers/buoy_parser.py", "drivers/thruster_protocol.py"]
PACKAGES = ["zarco_core", "drivers", "zarco_runtime", "zarco_tools", "hil", "config"]

#: one line of each type, as the simulator or a receiver writes it (body, driver)
SENTENCES: dict[str, tuple[str, str]] = {
    "GGA": ("GNGGA,120000.00,4111.10000000,N,00842.30000000,W,4,14,0.7,0.000,M,0.000,M,1.0,"
            "0000", "gps"),
    "RMC": ("GNRMC,120000.00,A,4111.10000000,N,00842.30000000,W,1.944,12.34,010626,,,R",
            "gps"),
    "VTG": ("GNVTG,12.34,T,,M,1.944,N,3.600,K,R", "gps"),
    "GST": ("GNGST,120000.00,0.015,0.015,0.015,0.0,0.015,0.015,0.030", "gps"),
    "ZDA": ("GNZDA,120000.00,01,06,2026,00,00", "gps"),
    "GLL": ("GNGLL,4111.10000000,N,00842.30000000,W,120000.00,A,R", "gps"),
    "GNS": ("GNGNS,120000.00,4111.10000000,N,00842.30000000,W,RR,14,0.7,0.000,0.000,1.0,"
            "0000,S", "gps"),
    "HDT": ("HEHDT,123.45,T", "gps"),
    "THS": ("HETHS,123.45,A", "gps"),
    "HDG": ("HCHDG,98.3,,,2.0,W", "compass"),
    "HDM": ("APHDM,218.634,M", "compass"),
    "ROT": ("TIROT,-12.34,A", "compass"),
    "XDR": ("YXXDR,A,0.4,D,PTCH,A,-1.2,D,ROLL", "compass"),
    "PZTHS": ("PZTHS,12.5,-3.0,1500,-700,3.2,1.1", "thrusters"),
    "PZTHR": ("PZTHR,12.5,-3.0", "thruster_controller"),
    "PZBAE": ("PZBAE,101502.123456,010626,I,2,18.5", "buoy"),
    "PZBST": ("PZBST,100001.00,010626,4111.100000,N,00842.300000,W,12.60,0", "buoy"),
}
#: the simulator's sentences per simulated second (GPS 10 Hz GGA/RMC/VTG, GST
#: and ZDA 1 Hz; compass 20 Hz HDG/ROT, XDR every 4th; thruster status 5 Hz;
#: commands 20 Hz): the weights of the mix figure
SIM_MIX = {"GGA": 10, "RMC": 10, "VTG": 10, "GST": 1, "ZDA": 1, "HDG": 20, "ROT": 20,
           "XDR": 5, "PZTHS": 5, "PZTHR": 20}


def log(msg: str) -> None:
    print(f"parsers: {msg}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------- workers


def _paths(pkg: str) -> dict[str, Any]:
    """The driver entry points of parser package ``pkg`` (``drivers`` or ``old_drivers``)."""
    import importlib

    gps = importlib.import_module(f"{pkg}.gps_parser")
    compass = importlib.import_module(f"{pkg}.compass_parser")
    buoy = importlib.import_module(f"{pkg}.buoy_parser")
    thr = importlib.import_module(f"{pkg}.thruster_protocol")
    nmea = importlib.import_module(f"{pkg}.nmea")
    return {"gps": lambda x: gps.parse_gps(x, 0.0),
            "compass": lambda x: compass.parse_compass(x, 0.0, variation_deg=-2.0),
            "buoy": lambda x: buoy.parse_buoy(x, 0.0),
            "thrusters": lambda x: thr.parse_pzths(x, 0.0),
            "thruster_controller": thr.parse_pzthr,
            "NmeaError": nmea.NmeaError, "NmeaFramer": nmea.NmeaFramer,
            "format_sentence": nmea.format_sentence}


def measure_types(rounds: int, number: int) -> dict[str, dict[str, list[float]]]:
    """CPU seconds per call of each type, old and new, in this process: batches
    of ``number`` calls, old and new alternately, ``rounds`` times, so both see
    the same load on a shared machine."""
    import time

    from drivers.nmea import format_sentence

    clock = time.process_time
    impl = {"old": _paths("old_drivers"), "new": _paths("drivers")}
    calls: dict[str, dict[str, Any]] = {"old": {}, "new": {}}
    for which, p in impl.items():
        err = p["NmeaError"]
        for stype, (body, path) in SENTENCES.items():
            line = format_sentence(body).decode().rstrip("\r\n")
            parse = p[path]

            def call(parse: Any = parse, line: str = line, err: Any = err) -> bool:
                try:
                    parse(line)
                    return True
                except err:
                    return False

            calls[which][stype] = call
        epoch = b"".join(format_sentence(SENTENCES[k][0]) for k in ("GGA", "RMC", "VTG"))
        framer = p["NmeaFramer"]()
        fmt = p["format_sentence"]
        gga = SENTENCES["GGA"][0]
        calls[which]["framing"] = lambda framer=framer, epoch=epoch: framer.feed(epoch)
        calls[which]["format"] = lambda fmt=fmt, gga=gga: fmt(gga)
    out: dict[str, dict[str, list[float]]] = {"old": {}, "new": {}}
    for r in range(rounds):
        for key in calls["new"]:
            for which in (("old", "new") if (r + len(key)) % 2 == 0 else ("new", "old")):
                f = calls[which][key]
                f()  # warm
                c0 = clock()
                for _ in range(number):
                    f()
                out[which].setdefault(key, []).append((clock() - c0) / number)
        if r % max(1, rounds // 5) == 0:
            log(f"types round {r + 1}/{rounds}: GGA old {out['old']['GGA'][-1] * 1e6:.1f} µs, "
                f"new {out['new']['GGA'][-1] * 1e6:.1f} µs")
    out["accepted"] = {w: {k: float(calls[w][k]()) for k in SENTENCES} for w in calls}
    return out


def worker_sim(seed: int, estimator: str) -> dict[str, Any]:
    """The rectangle in this tree: wall-clock speedup (the simulator's own
    figure) and simulated seconds per CPU second of this process."""
    import time

    from zarco_tools.scenario import load_scenario
    from zarco_tools.simulation import run_scenario

    spent = instrument_byte_path()
    scn = load_scenario(Path("config") / "scenarios" / "rectangle.toml",
                        [f"runtime.navigation.estimator={estimator}"], seed)
    c0 = time.process_time()
    rep = run_scenario(scn).report
    cpu = time.process_time() - c0
    wall = rep["wall_seconds"]
    return {"speedup": rep["speedup"], "speedup_cpu": rep["sim_seconds"] / cpu,
            "share": {k: v / wall for k, v in spent.items()}}


#: where the runtime and the simulator enter the byte path: (module, name, part)
BYTE_PATH = [("zarco_runtime.runtime", "parse_gps", "parse"),
             ("zarco_runtime.runtime", "parse_compass", "parse"),
             ("zarco_runtime.runtime", "parse_buoy", "parse"),
             ("drivers.thruster_driver", "parse_pzths", "parse"),
             ("drivers.sim.backend", "parse_pzthr", "parse"),
             ("drivers.sim.sensors", "format_sentence", "format"),
             ("drivers.sim.acoustics", "encode_pzbae", "format"),
             ("drivers.sim.acoustics", "encode_pzbst", "format"),
             ("drivers.thruster_driver", "encode_pzthr", "format")]


def instrument_byte_path() -> dict[str, float]:
    """Wrap the byte path's entry points (parsing, framing, formatting) with
    wall-clock accumulators; the shares of the run's wall time they took say
    what the parsers weigh in the simulation (the wrappers cost ~0.3 µs a call,
    the same in old and new)."""
    import importlib
    import time

    spent = {"parse": 0.0, "framing": 0.0, "format": 0.0}
    clock = time.perf_counter

    def wrap(owner: Any, name: str, part: str) -> None:
        f = getattr(owner, name, None)
        if f is None:
            return

        def timed(*a: Any, **k: Any) -> Any:
            c0 = clock()
            try:
                return f(*a, **k)
            finally:
                spent[part] += clock() - c0

        setattr(owner, name, timed)

    for mod, name, part in BYTE_PATH:
        wrap(importlib.import_module(mod), name, part)
    wrap(importlib.import_module("drivers.nmea").NmeaFramer, "feed", "framing")
    return spent


# ----------------------------------------------------------------- driver


def base_commit(rev: str | None) -> str:
    """``rev``, or the parent of the commit that took pynmea2 out of drivers/nmea.py."""
    git = ["git", "-C", str(ROOT)]
    if rev:
        return subprocess.check_output([*git, "rev-parse", rev], text=True).strip()
    removed = subprocess.check_output(
        [*git, "log", "-1", "--format=%H", "-S", "import pynmea2", "--", "drivers/nmea.py"],
        text=True).strip()
    return subprocess.check_output([*git, "rev-parse", f"{removed}^"], text=True).strip()


def make_old_tree(base: str, where: Path) -> Path:
    """This tree's packages with the parser modules of ``base``."""
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, where / pkg,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for f in PARSER_FILES:
        text = subprocess.check_output(["git", "-C", str(ROOT), "show", f"{base}:{f}"])
        (where / f).write_bytes(text)
    return where


def make_old_package(base: str, where: Path) -> None:
    """``where/old_drivers``: the parser modules of ``base``, importing each other
    as ``old_drivers.*`` (and everything else from this tree)."""
    pkg = where / "old_drivers"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for f in PARSER_FILES:
        text = subprocess.check_output(["git", "-C", str(ROOT), "show", f"{base}:{f}"], text=True)
        (where / "old_drivers" / Path(f).name).write_text(
            text.replace("from drivers.", "from old_drivers.").replace(
                "import drivers.", "import old_drivers."))


def run_worker(root: Path, args: list[str]) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", *args, "--root", str(root)]
    res = subprocess.run(cmd, cwd=root, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"worker {args} in {root} failed:\n{res.stderr[-2000:]}")
    out: dict[str, Any] = json.loads(res.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=40, help="alternating batches per type")
    ap.add_argument("--number", type=int, default=500, help="calls per batch")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--sim-rounds", type=int, default=2)
    ap.add_argument("--estimator", default="ekf")
    ap.add_argument("--base", default=None)
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--root", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker is not None:
        sys.path.insert(0, args.root)
        print(json.dumps(worker_sim(int(args.worker[0]), args.worker[1])))
        return

    base = base_commit(args.base)
    log(f"old = parser modules of {base[:10]}, new = this tree")
    with tempfile.TemporaryDirectory(prefix="zarco-bench-parsers-") as tmp:
        old_root = Path(tmp) / "old"
        old_root.mkdir()
        roots = {"old": make_old_tree(base, old_root), "new": ROOT}
        pkg_dir = Path(tmp) / "pkg"
        pkg_dir.mkdir()
        make_old_package(base, pkg_dir)
        sys.path[:0] = [str(ROOT), str(pkg_dir)]
        per = measure_types(args.rounds, args.number)
        accepted = per.pop("accepted")
        med = {w: {k: statistics.median(v) for k, v in per[w].items()} for w in per}
        types = {}
        for k in SENTENCES:
            o, n = med["old"][k], med["new"][k]
            types[k] = {"old_per_s": round(1.0 / o), "new_per_s": round(1.0 / n),
                        "old_us": round(o * 1e6, 2), "new_us": round(n * 1e6, 2),
                        "ratio": round(o / n, 2), "old_accepted": bool(accepted["old"][k])}
        mix = {w: sum(med[w][k] * c for k, c in SIM_MIX.items()) for w in med}
        out: dict[str, Any] = {
            "bench": "parsers", "base": base[:12], "rounds": args.rounds,
            "types": types,
            "framing_us_per_epoch": {w: round(med[w]["framing"] * 1e6, 2) for w in med},
            "format_us": {w: round(med[w]["format"] * 1e6, 2) for w in med},
            # parse cost of one simulated second of the simulator's sentences
            "sim_mix_parse_ms_per_sim_s": {w: round(mix[w] * 1e3, 3) for w in mix},
            "sim_mix_ratio": round(mix["old"] / mix["new"], 2),
        }
        for k, v in types.items():
            log(f"{k:6s} old {v['old_us']:7.2f} µs  new {v['new_us']:7.2f} µs  ×{v['ratio']}"
                + ("" if v["old_accepted"] else "  (old: refused)"))
        if not args.no_sim:
            sims: dict[str, list[float]] = {"old": [], "new": []}
            cpus: dict[str, list[float]] = {"old": [], "new": []}
            shares: dict[str, dict[str, list[float]]] = {"old": {}, "new": {}}
            for r in range(args.sim_rounds):
                for seed in args.seeds:
                    for which in (("old", "new") if (r + seed) % 2 == 0 else ("new", "old")):
                        res = run_worker(roots[which], [str(seed), args.estimator])
                        sims[which].append(res["speedup"])
                        cpus[which].append(round(res["speedup_cpu"], 1))
                        for part, v in res["share"].items():
                            shares[which].setdefault(part, []).append(v)
                        log(f"rectangle seed {seed} ({args.estimator}) {which}: "
                            f"{res['speedup']:.1f}× real time, "
                            f"{res['speedup_cpu']:.1f} sim s per CPU s")
            so, sn = statistics.median(sims["old"]), statistics.median(sims["new"])
            co, cn = statistics.median(cpus["old"]), statistics.median(cpus["new"])
            out["sim"] = {"scenario": "rectangle", "estimator": args.estimator,
                          "seeds": args.seeds, "old_speedup": round(so, 1),
                          "new_speedup": round(sn, 1), "ratio": round(sn / so, 3),
                          "old_speedup_cpu": round(co, 1), "new_speedup_cpu": round(cn, 1),
                          "ratio_cpu": round(cn / co, 3),
                          # share of the run's wall time in each part of the byte path
                          "byte_path_share": {w: {k: round(statistics.median(v), 4)
                                                  for k, v in shares[w].items()}
                                              for w in shares},
                          "old_runs": sims["old"], "new_runs": sims["new"],
                          "old_runs_cpu": cpus["old"], "new_runs_cpu": cpus["new"]}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
