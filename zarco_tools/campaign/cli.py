"""``zarco campaign``: validate a tuning over many randomised missions, on this
computer's cores or on a Dask cluster.

::

    zarco campaign SPEC.toml [--n N] [--seed S] [--set KEY=VALUE ...] [--out DIR]
                             [--choice NAME=VALUE[:WEIGHT],...] [--jobs N]
                             [--scheduler tcp://HOST:8786]
    zarco campaign compare A B [--out FILE.json]

Registered through the ``zarco.commands`` entry point; the heavy modules load
only when a campaign runs.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from zarco_core.config import ConfigError
from zarco_core.paths import writable_dir


def _interrupt(signum: int, frame: object) -> None:
    """SIGTERM handler: the campaign stops as on Ctrl-C (KeyboardInterrupt)."""
    raise KeyboardInterrupt


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be ≥ 1, got {v}")
    return v


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be ≥ 0, got {v}")
    return v


class Progress:
    """One line per finished mission on ``stream``: count, rate, time left."""

    def __init__(self, total: int, done: int, stream: TextIO | None = None) -> None:
        self.total, self.done0, self.n = total, done, done
        self.w0 = time.perf_counter()
        # the stderr of when it runs, not of when the module was imported
        self.stream = stream if stream is not None else sys.stderr

    def __call__(self, rec: dict[str, Any]) -> None:
        self.n += 1
        el = time.perf_counter() - self.w0
        ran = self.n - self.done0
        rate = ran / el * 60.0 if el > 0 else 0.0
        left = (self.total - self.n) / (ran / el) if ran and el > 0 else float("nan")
        eta = f"{left / 60:4.1f} min" if left == left else "   ?"
        fails = sorted(rec.get("fails", {}))
        status = "ok" if not fails else "MISS " + ",".join(fails)
        if rec.get("exempt"):
            status += " (exempt " + ",".join(sorted(rec["exempt"])) + ")"
        self.stream.write(f"[{self.n:5d}/{self.total} {rate:5.1f}/min left {eta}] "
                          f"m{rec['index']:04d} {rec['family']:<16} severity "
                          f"{rec['severity']:6.2f}  {rec.get('wall_s', 0):5.1f} s  {status}\n")
        self.stream.flush()


def cmd_campaign(args: argparse.Namespace) -> int:
    if args.spec == "compare":
        return cmd_compare(args)
    if args.paths:
        raise ConfigError("zarco campaign", args.paths[0], "unexpected argument (only "
                          "`zarco campaign compare A B` takes two)")
    from zarco_tools.campaign.draw import draw_mission, drawer
    from zarco_tools.campaign.plots import factor_effects, format_effects, plot_campaign
    from zarco_tools.campaign.results import ResultsDir
    from zarco_tools.campaign.run import run_dask, run_local
    from zarco_tools.campaign.spec import load_spec, parse_choice, with_choices
    from zarco_tools.campaign.tables import format_summary, summarise
    from zarco_tools.scenario import scenario_from_data

    spec = load_spec(args.spec)
    choices = dict(parse_choice(c, spec.kind) for c in args.choice)
    spec = with_choices(spec, choices)
    n = args.n or spec.missions
    sets = list(args.set)
    # a bad --set is refused before anything runs
    m0 = draw_mission(spec, args.seed, 0)
    scenario_from_data(spec.scenario_data(), f"{spec.scenario_file}", [*m0.overrides, *sets],
                       m0.scenario_seed)
    if args.out:  # the operator's directory: its parent must exist (nothing made above it)
        out = writable_dir(args.out, "--out", create=True)
    else:  # the default place, made as needed
        out = Path("out") / "campaign" / f"{spec.name}-seed{args.seed}"
        out.mkdir(parents=True, exist_ok=True)
    checks = list(drawer(spec.kind).checks)
    header = {"name": spec.name, "kind": spec.kind, "spec": spec.file, "digest": spec.digest,
              "scenario": spec.scenario_file, "seed": args.seed, "sets": sets,
              "checks": checks, "targets": spec.targets}
    if choices:
        header["choices"] = choices
    store = ResultsDir(out, header)
    store.open()
    wanted = sorted(set(args.only)) if args.only else list(range(n))
    todo = [k for k in wanted if k not in store.done]
    where = (f"the Dask cluster at {args.scheduler}" if args.scheduler
             else f"{args.jobs} local processes")
    print(f"campaign {spec.name} seed {args.seed}: {len(wanted)} missions, "
          f"{len(wanted) - len(todo)} already in {out / 'results.jsonl'}"
          f"{f' ({store.dropped} cut short, run again)' if store.dropped else ''}, "
          f"{len(todo)} to run on {where}", file=sys.stderr, flush=True)
    progress = Progress(len(wanted), len(wanted) - len(todo))
    if todo:
        if args.scheduler:
            try:
                import distributed  # noqa: F401
            except ImportError:
                raise ConfigError("zarco campaign", "--scheduler", "needs Dask's distributed: "
                                  "pip install 'zarco-runtime[cluster]'") from None
            stream = run_dask(spec, args.seed, todo, sets, args.scheduler)
        else:
            stream = run_local(spec, args.seed, todo, sets, args.jobs)
        # a TERM (the job killed, a time limit) stops it as Ctrl-C does: the
        # workers are ended with it, not left running their missions
        old_term = signal.signal(signal.SIGTERM, _interrupt)
        try:
            for rec in stream:
                store.append(rec)
                progress(rec)
        except KeyboardInterrupt:
            stream.close()
            store.close()
            print(f"interrupted: {len(store.done)} missions in {out / 'results.jsonl'}; "
                  "the same command resumes", file=sys.stderr)
            return 130
        finally:
            signal.signal(signal.SIGTERM, old_term)
    store.close()
    records = [store.done[k] for k in wanted if k in store.done]
    summary = summarise(records, tuple(checks), spec.scenario_file, sets, worst=args.worst)
    effects = factor_effects(records, checks)
    summary["factor_effects"] = effects
    summary["campaign"] = header
    summary["wall_s"] = round(time.perf_counter() - progress.w0, 1)
    (out / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
    print(f"campaign {spec.name} ({spec.file}) seed {args.seed}, {len(records)} missions"
          f"{', --choice ' + ' '.join(args.choice) if args.choice else ''}"
          f"{', --set ' + ' '.join(sets) if sets else ''}")
    print(format_summary(summary))
    if effects:
        print()
        print(format_effects(effects))
    files = [str(out / "results.jsonl"), str(out / "summary.json")]
    if not args.no_plots and records:
        files += plot_campaign(out, records, checks, f"{spec.name} seed {args.seed}",
                               spec.targets)
    print("\n" + "written: " + ", ".join(files))
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from zarco_tools.campaign.compare import compare, format_compare, write_compare

    if len(args.paths) != 2:
        raise ConfigError("zarco campaign compare", "", "needs two result sets: "
                          "zarco campaign compare A B")
    c = compare(args.paths[0], args.paths[1])
    print(format_compare(c))
    if args.out:
        write_compare(c, args.out)
        print(f"\nwritten: {args.out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``campaign`` to the ``zarco`` parser."""
    c = sub.add_parser(
        "campaign", help="run a randomised campaign of simulated missions and judge it",
        description="Draw N missions from a campaign spec (config/campaigns/*.toml), "
        "simulate each (zarco sim) on local processes or a Dask cluster, write each result "
        "as it arrives to DIR/results.jsonl (a rerun resumes), and print the pass table "
        "per target and family, the worst missions with the command that reproduces each, "
        "and plots of the figures against the drawn factors. "
        "`zarco campaign compare A B` sets two result sets of the same missions side by "
        "side.")
    c.add_argument("spec", metavar="SPEC.toml|compare",
                   help="campaign spec file, or `compare` followed by two output dirs")
    c.add_argument("paths", nargs="*", metavar="A B", help="(compare) two campaigns' output "
                   "directories or results.jsonl files")
    c.add_argument("--n", type=_positive_int, default=None,
                   help="missions (default: the spec's `missions`)")
    c.add_argument("--seed", type=_seed, default=1, help="campaign seed (default 1)")
    c.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key in every mission (repeatable), e.g. a "
                   "runtime setting under test: runtime.follow.k_s=0.2")
    c.add_argument("--choice", action="append", default=[],
                   metavar="NAME=VALUE[:WEIGHT],...",
                   help="draw a category with these weights in every family instead of the "
                   "spec's (repeatable); the rest of each mission's draw stays the same, "
                   "e.g. --choice plan=plan and --choice plan=none: the same missions with "
                   "and without the AUV's plan")
    c.add_argument("--out", default=None, metavar="DIR",
                   help="output directory (default out/campaign/NAME-seedS); "
                   "(compare) write the comparison as JSON here")
    c.add_argument("--jobs", type=_positive_int, default=os.cpu_count() or 1,
                   help="local worker processes (default: the cores)")
    c.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run on the Dask distributed cluster whose scheduler is here "
                   "(tcp://HOST:8786) instead of local processes")
    c.add_argument("--only", type=int, nargs="+", default=None, metavar="K",
                   help="run only these mission indices")
    c.add_argument("--worst", type=int, default=5, help="worst missions listed (default 5)")
    c.add_argument("--no-plots", action="store_true", help="skip the plots")
    c.set_defaults(func=cmd_campaign)
