"""``zarco log``: read, plot, export and replay recordings (MCAP)."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from pathlib import Path

from zarco_core.paths import PathError, oserror_reason, writable_file


def cmd_info(args: argparse.Namespace) -> int:
    from zarco_tools.log.info import format_info, summarize
    from zarco_tools.log.reader import open_recording

    s = summarize(open_recording(args.files))
    print(json.dumps(s) if args.json else format_info(s))
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    from zarco_tools.log.plot import plot_recording
    from zarco_tools.log.reader import open_recording
    from zarco_tools.plot import image_path

    out = args.out or str(Path(args.files[0]).with_suffix(".png"))
    rec = open_recording(args.files)
    image_path(out, "--out")
    f = plot_recording(rec, out)
    print(f"plot: {out} ({f.kind}, {'truth' if f.truth else 'estimate'}, "
          f"{len(f.log.t)} samples)")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from zarco_tools.log.export import export
    from zarco_tools.log.reader import open_recording

    rec = open_recording(args.files)
    fmt = "jsonl" if args.jsonl else "csv"
    if args.out:
        writable_file(args.out, "--out")
        try:
            with open(args.out, "w", newline="", encoding="utf-8") as fh:
                n = export(rec, args.topic, fh, fmt)
        except OSError as exc:  # a full disk, a quota: nothing half-written is left
            if Path(args.out).is_file():  # never a device such as /dev/full
                with contextlib.suppress(OSError):
                    os.unlink(args.out)
            print(f"zarco log export: --out: {args.out}: cannot write it: "
                  f"{oserror_reason(exc)}", file=sys.stderr)
            return 1
    else:
        n = export(rec, args.topic, sys.stdout, fmt)  # a closed pipe (| head): quiet
    if n == 0:
        print(f"zarco log export: no messages on {args.topic}", file=sys.stderr)
        return 1
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from zarco_tools.log.reader import open_recording
    from zarco_tools.log.replay import replay, report

    rec = open_recording(args.files)
    if args.record:
        writable_file(args.record, "--record")
    res = replay(rec, args.set, args.record)
    r = report(res)
    failed = 0
    if res.record_error:
        print(f"zarco log replay: --record: {args.record}: recording failed: "
              f"{res.record_error}", file=sys.stderr)
        failed = 1
    if args.json:
        print(json.dumps(r))
        return failed
    nav, fix, trk, cmd = r["nav"], r["auv_fix"], r["auv_track"], r["thruster_commands"]
    print(f"replayed {r['chunks']} raw chunks and {cmd['replayed']} thruster commands: "
          f"{r['sim_seconds']:.1f} s in {r['wall_seconds']:.2f} s = "
          f"{r['speed_x_realtime']:.0f}× real time")
    for name, d in (("NavState", nav), ("AuvFix", fix), ("AuvTrack", trk)):
        state = "identical" if d["exact"] else f"{d['different']} differ"
        if d.get("first_difference_t") is not None:
            state += f" (first at t = {d['first_difference_t']:.3f} s)"
        print(f"  {name:9s} recorded {d['recorded']:6d}  replayed {d['replayed']:6d}  {state}")
    if nav["compared"]:
        print(f"  position: replay − recording RMS {nav['position_rms_m']:.4f} m, "
              f"max {nav['position_max_m']:.4f} m")
    notes = []
    if r["cut_short"]:
        notes.append("the recording was cut short (its writer killed): compared up to its end")
    if r["late"] or r["lost"]:
        notes.append(f"{r['late']} inputs played late, {r['lost']} chunks not read "
                     "(a port the replayed driver had closed)")
    if r["params_applied"]:
        notes.append(f"{r['params_applied']} parameter changes applied at their times")
    notes += [f"parameter change refused here: {why}" for why in r["params_refused"]]
    for n in notes:
        print(f"  note: {n}")
    if args.record and os.path.isfile(args.record):
        print(f"record: {args.record}" + (" (incomplete)" if failed else ""))
    return failed


def cmd_fix(args: argparse.Namespace) -> int:
    from zarco_tools.log.reader import open_recording, recover

    out = args.out or str(Path(args.file).with_suffix(".fixed.mcap"))
    open_recording(args.file)
    writable_file(out, "--out")
    if os.path.lexists(out):
        raise PathError(out, "already exists (a recovered file is never written over one)",
                        "--out")
    n, why = recover(args.file, out)
    print(f"{out}: {n} messages" + (f" (source ended: {why})" if why else
                                    " (source was finished)"))
    return 0


def register_log(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    lg = sub.add_parser("log", help="read, plot, export and replay recordings (MCAP)",
                        description="Recordings are MCAP files written by the recorder "
                        "(zarco run: [record] dir; zarco sim --record FILE). FILE may be "
                        "several files: the parts of one run, in order. A file whose writer "
                        "was killed is read up to its last complete chunk.")
    s = lg.add_subparsers(dest="log_command", required=True)
    i = s.add_parser("info", help="duration, topics, counts, gaps, faults, mode changes")
    i.add_argument("files", nargs="+", metavar="FILE")
    i.add_argument("--json", action="store_true", help="one JSON object instead of text")
    i.set_defaults(func=cmd_info)
    p = s.add_parser("plot", help="the paper's figures (4, 5 for lines; 7, 8, 9 for "
                     "follow) from a recording")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.add_argument("-o", "--out", metavar="FILE.png", help="default: FILE with .png")
    p.set_defaults(func=cmd_plot)
    e = s.add_parser("export", help="one topic as CSV (or JSON lines)")
    e.add_argument("files", nargs="+", metavar="FILE")
    e.add_argument("--topic", required=True, help="e.g. /NavState, /raw/gps/rx "
                   "(zarco log info lists them)")
    e.add_argument("--csv", action="store_true", help="CSV (the default)")
    e.add_argument("--jsonl", action="store_true", help="JSON lines instead of CSV")
    e.add_argument("-o", "--out", metavar="FILE", help="default: standard output")
    e.set_defaults(func=cmd_export)
    r = s.add_parser("replay", help="the recorded raw device bytes and thruster commands "
                     "through the runtime's drivers, estimator and tracker again (virtual "
                     "clock)",
                     description="Builds the runtime from the recorded configuration "
                     "(changed by --set: a tuning to judge), plays every recorded device "
                     "chunk, the thruster commands the boat sent (the estimator's input: the "
                     "control task does not run) and the operator's commands at their "
                     "recorded times and in the recorded order, and compares the navigation "
                     "and AUV track with the recorded ones (a simulation's recording: "
                     "identical).")
    r.add_argument("files", nargs="+", metavar="FILE")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="change a runtime setting for the replay (repeatable), e.g. "
                   "ekf.gps_latency_s=0.1 or tracker.timing_sigma_s=0.002 (control "
                   "settings change nothing: the commands are the recorded ones)")
    r.add_argument("--record", metavar="OUT.mcap", help="record the replay")
    r.add_argument("--json", action="store_true", help="one JSON line of figures")
    r.set_defaults(func=cmd_replay)
    f = s.add_parser("fix", help="rewrite a file whose writer was killed as a finished one "
                     "(summary and indexes, for tools that need them)")
    f.add_argument("file", metavar="FILE")
    f.add_argument("-o", "--out", metavar="OUT.mcap", help="default: FILE.fixed.mcap")
    f.set_defaults(func=cmd_fix)
