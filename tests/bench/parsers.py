"""Benchmark: the NMEA byte path, pynmea2 on it (old) against our own split (new).

    python tests/bench/parsers.py [--rounds 5] [--seeds 1 2] [--base REV] [--no-sim]

"Old" is this tree with the five parser modules (``drivers/nmea.py``,
``gps_parser.py``, ``compass_parser.py``, ``buoy_parser.py``,
``thruster_protocol.py``) taken from ``--base``: by default the last commit
whose ``drivers/nmea.py`` still imported pynmea2.  Everything else (the
simulator, the EKF, the runtime) is the same code, so the ratio is the
parsers' alone.  Old and new run in separate processes, alternately, round
after round, on the same sentences and seeds; figures are medians over the
rounds.

Measured:

* per sentence type, sentences per second through the driver entry point
  (``parse_gps`` / ``parse_compass`` / ``parse_buoy`` / ``parse_pzths`` /
  ``parse_pzthr``), best of several repeats per round; GLL and GNS were not
  read before (``unsupported``), so their old figure is the cost of the
  refusal;
* framing (``NmeaFramer.feed`` on one simulated GPS epoch) and sentence
  formatting with its checksum (``format_sentence``, used by the simulated
  devices);
* the rectangle scenario with the EKF (``runtime.navigation.estimator=ekf``):
  simulated seconds per wall second (``speedup``), per seed.

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


def worker_types(number: int, repeat: int) -> dict[str, Any]:
    """Seconds per call of each type, and of framing and formatting (this tree)."""
    import timeit

    from drivers.buoy_parser import parse_buoy
    from drivers.compass_parser import parse_compass
    from drivers.gps_parser import parse_gps
    from drivers.nmea import NmeaError, NmeaFramer, format_sentence
    from drivers.thruster_protocol import parse_pzthr, parse_pzths

    paths = {"gps": lambda x: parse_gps(x, 0.0),
             "compass": lambda x: parse_compass(x, 0.0, variation_deg=-2.0),
             "buoy": lambda x: parse_buoy(x, 0.0), "thrusters": lambda x: parse_pzths(x, 0.0),
             "thruster_controller": parse_pzthr}
    out: dict[str, Any] = {}
    for stype, (body, path) in SENTENCES.items():
        line = format_sentence(body).decode().rstrip("\r\n")
        parse = paths[path]
        try:
            parse(line)
            accepted = True
        except NmeaError:
            accepted = False

        def call(parse: Any = parse, line: str = line) -> None:
            try:  # noqa: SIM105 - contextlib.suppress would weigh on the timing
                parse(line)
            except NmeaError:
                pass

        best = min(timeit.repeat(call, number=number, repeat=repeat)) / number
        out[stype] = {"s": best, "accepted": accepted}
    epoch = b"".join(format_sentence(SENTENCES[k][0]) for k in ("GGA", "RMC", "VTG"))
    framer = NmeaFramer()
    out["framing"] = {"s": min(timeit.repeat(lambda: framer.feed(epoch), number=number,
                                             repeat=repeat)) / number, "bytes": len(epoch)}
    body = SENTENCES["GGA"][0]
    out["format"] = {"s": min(timeit.repeat(lambda: format_sentence(body), number=number,
                                            repeat=repeat)) / number}
    return out


def worker_sim(seed: int, estimator: str) -> dict[str, Any]:
    from zarco_tools.scenario import load_scenario
    from zarco_tools.simulation import run_scenario

    scn = load_scenario(Path("config") / "scenarios" / "rectangle.toml",
                        [f"runtime.navigation.estimator={estimator}"], seed)
    rep = run_scenario(scn).report
    return {"speedup": rep["speedup"], "wall_s": rep.get("wall_s"),
            "duration_s": rep.get("duration_s")}


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


def run_worker(root: Path, args: list[str]) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", *args, "--root", str(root)]
    res = subprocess.run(cmd, cwd=root, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"worker {args} in {root} failed:\n{res.stderr[-2000:]}")
    out: dict[str, Any] = json.loads(res.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--number", type=int, default=3000, help="calls per timing")
    ap.add_argument("--repeat", type=int, default=5, help="timings per round (best kept)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--sim-rounds", type=int, default=2)
    ap.add_argument("--estimator", default="ekf")
    ap.add_argument("--base", default=None)
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--worker", nargs="*", help=argparse.SUPPRESS)
    ap.add_argument("--root", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker is not None:
        sys.path.insert(0, args.root)
        kind, *rest = args.worker
        if kind == "types":
            print(json.dumps(worker_types(int(rest[0]), int(rest[1]))))
        else:
            print(json.dumps(worker_sim(int(rest[0]), rest[1])))
        return

    base = base_commit(args.base)
    log(f"old = parser modules of {base[:10]}, new = this tree")
    with tempfile.TemporaryDirectory(prefix="zarco-bench-parsers-") as tmp:
        roots = {"old": make_old_tree(base, Path(tmp)), "new": ROOT}
        per: dict[str, dict[str, list[float]]] = {"old": {}, "new": {}}
        accepted: dict[str, dict[str, bool]] = {"old": {}, "new": {}}
        for r in range(args.rounds):
            for which in (("old", "new") if r % 2 == 0 else ("new", "old")):
                res = run_worker(roots[which], ["types", str(args.number), str(args.repeat)])
                for k, v in res.items():
                    per[which].setdefault(k, []).append(v["s"])
                    if "accepted" in v:
                        accepted[which][k] = v["accepted"]
            log(f"types round {r + 1}/{args.rounds}: GGA old "
                f"{per['old']['GGA'][-1] * 1e6:.1f} µs, new {per['new']['GGA'][-1] * 1e6:.1f} µs")
        med = {w: {k: statistics.median(v) for k, v in per[w].items()} for w in per}
        types = {}
        for k in SENTENCES:
            o, n = med["old"][k], med["new"][k]
            types[k] = {"old_per_s": round(1.0 / o), "new_per_s": round(1.0 / n),
                        "old_us": round(o * 1e6, 2), "new_us": round(n * 1e6, 2),
                        "ratio": round(o / n, 2), "old_accepted": accepted["old"][k]}
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
            for r in range(args.sim_rounds):
                for seed in args.seeds:
                    for which in (("old", "new") if (r + seed) % 2 == 0 else ("new", "old")):
                        res = run_worker(roots[which], ["sim", str(seed), args.estimator])
                        sims[which].append(res["speedup"])
                        log(f"rectangle seed {seed} ({args.estimator}) {which}: "
                            f"{res['speedup']:.1f}× real time")
            so, sn = statistics.median(sims["old"]), statistics.median(sims["new"])
            out["sim"] = {"scenario": "rectangle", "estimator": args.estimator,
                          "seeds": args.seeds, "old_speedup": round(so, 1),
                          "new_speedup": round(sn, 1), "ratio": round(sn / so, 3),
                          "old_runs": sims["old"], "new_runs": sims["new"]}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
