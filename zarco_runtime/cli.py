"""``zarco`` command line.

``zarco run`` (the boat) is built in.  Every other sub-command (``sim``,
``hil``, ``decode``, ``replay``, ``navreport``, ...) belongs to a package that
stands beside the onboard runtime (the simulator, HIL, evaluation tools) and
is found through the ``zarco.commands`` entry points, loaded only when one of
them is asked for: ``zarco run`` never imports the simulator, HIL, plotting
or evaluation code.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from typing import Any

from zarco_core.config import ConfigError
from zarco_core.paths import PathError, oserror_reason, writable_file


def cmd_run(args: argparse.Namespace) -> int:
    from zarco_runtime.vessel import run_vessel

    if args.status:
        writable_file(args.status, "--status")  # appended to: checked before the start
    return run_vessel(args.config, args.set, args.status)


def _not_json(word: str) -> Any:
    raise json.JSONDecodeError(f"{word} is not a JSON number", word, 0)


def _json_text(text: str) -> str:
    """``text`` on one line, as typed: not re-encoded, so the runtime's command
    schema judges the operator's own numbers (``1e999`` is refused there naming
    its field, where ``json.dumps`` would have made it ``Infinity``) and its
    nesting.  Raises ``json.JSONDecodeError`` when ``text`` is not JSON (Python's
    ``NaN`` and ``Infinity`` included)."""
    try:
        json.loads(text, parse_constant=_not_json)
    except json.JSONDecodeError:
        raise
    except (ValueError, RecursionError):
        pass  # JSON too deep or too long a number for Python: the runtime refuses it
    # JSON's strings hold no raw line breaks: these are whitespace between tokens
    return text.replace("\r", " ").replace("\n", " ")


def cmd_ctl(args: argparse.Namespace) -> int:
    """``zarco ctl``: one command to a running runtime over its local socket."""
    import socket

    listing = args.name in ("status", "params")
    if listing:
        line = json.dumps({"name": args.name})
    elif args.name == "param" and len(args.args) == 2:  # zarco ctl param NAME VALUE
        try:
            value = _json_text(args.args[1])
        except json.JSONDecodeError:
            value = json.dumps(args.args[1])  # a word: one of the parameter's choices
        line = (f'{{"name": "param", "args": {{"name": {json.dumps(args.args[0])}, '
                f'"value": {value}}}}}')
    elif args.name == "param" and len(args.args) == 1 \
            and not args.args[0].lstrip().startswith("{"):
        print("zarco ctl: param NAME VALUE (e.g. `zarco ctl param failsafe.link_lost_s 20`), "
              "or one JSON object", file=sys.stderr)
        return 2
    elif len(args.args) > 1:
        print("zarco ctl: one ARGS (a JSON object), or `param NAME VALUE`", file=sys.stderr)
        return 2
    else:
        try:
            cmd_args = _json_text(args.args[0]) if args.args else "{}"
        except json.JSONDecodeError as exc:
            print(f"zarco ctl: ARGS is not JSON: {exc}", file=sys.stderr)
            return 2
        line = f'{{"name": {json.dumps(args.name)}, "args": {cmd_args}}}'
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(5.0)
            s.connect(args.socket)
            s.sendall((line + "\n").encode("utf-8", "surrogateescape"))
            buf = b""
            while not buf.endswith(b"\n"):
                chunk = s.recv(65536)
                if not chunk:
                    break
                buf += chunk
    except OSError as exc:
        print(f"zarco ctl: {args.socket}: {oserror_reason(exc)} (is the runtime running, "
              "with this supervisor.control_socket?)", file=sys.stderr)
        return 2
    try:
        reply = json.loads(buf or b"{}")
        # an object; `params` is answered with a list (or an object refusing it)
        if not isinstance(reply, dict) and not (args.name == "params"
                                                and isinstance(reply, list)):
            raise ValueError("not an object")
    except ValueError:
        print(f"zarco ctl: {args.socket}: not a reply of a zarco runtime: {buf[:80]!r}",
              file=sys.stderr)
        return 2
    print(json.dumps(reply, indent=2 if listing else None))
    if isinstance(reply, dict) and "ok" in reply and not reply["ok"]:
        print(f"zarco ctl: refused: {reply.get('reason')}", file=sys.stderr)
        return 1
    return 0


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="zarco", description="Zarco ASV runtime")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run on the vessel (real devices)")
    r.add_argument("--config", required=True, help="runtime TOML (config/zarco.toml)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    r.add_argument("--status", metavar="FILE.jsonl", help="append the 1 Hz status snapshot "
                   "and every event here (JSON lines), and a final line on exit")
    r.set_defaults(func=cmd_run)

    c = sub.add_parser("ctl", help="send a command to a running runtime (local socket)",
                       description="Send one command to the supervisor of a running "
                       "`zarco run` over its supervisor.control_socket and print its "
                       "acknowledgement (exit 1 if refused). NAME: stop, arm, disarm, mode, "
                       "mission, follow, thrust, resume, param, or status (the latest status "
                       "snapshot), params (every parameter, its range and value). ARGS: the "
                       "command's arguments as JSON, e.g. '{\"mode\": \"hold\"}'; for "
                       "param, NAME VALUE: `zarco ctl param failsafe.link_lost_s 20`.")
    c.add_argument("--socket", required=True, help="the runtime's control socket")
    c.add_argument("name", help="command name, or status, or params")
    c.add_argument("args", nargs="*", default=[], help="arguments as a JSON object (param: "
                   "NAME VALUE)")
    c.set_defaults(func=cmd_ctl)

    for ep in _tool_commands(argv):
        ep.load()(sub)
    return p


#: sub-commands of this module; any other comes from a ``zarco.commands`` entry point
BUILTIN = ("run", "ctl")


def _tool_commands(argv: list[str] | None) -> list[Any]:
    """The ``zarco.commands`` entry points to load for ``argv``: none for a built-in
    sub-command, else all of them (``zarco --help`` lists every command)."""
    args = sys.argv[1:] if argv is None else argv
    words = [a for a in args if not a.startswith("-")]
    if words and words[0] in BUILTIN:
        return []
    from importlib.metadata import entry_points

    return sorted(entry_points(group="zarco.commands"), key=lambda e: e.name)


def _quiet_stdout() -> None:
    """The reader of standard output has gone (``zarco ctl status | head``): send
    whatever is still buffered nowhere, so that exiting prints no error."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def main(argv: list[str] | None = None) -> int:
    """Run one ``zarco`` command; its exit status.  A configuration or a path
    it cannot use is one line on stderr and exit 2; a reader that closes the
    pipe early ends the command quietly (exit 0)."""
    args = build_parser(argv).parse_args(argv)
    from zarco_runtime.logs import setup, under_journal

    setup(args.verbose, service=args.command == "run" and under_journal())
    # the command's full name: "zarco log info", "zarco shore status", ...
    sub = getattr(args, f"{args.command}_command", None)
    name = f"zarco {args.command}" + (f" {sub}" if isinstance(sub, str) else "")
    try:
        code = int(args.func(args))
        sys.stdout.flush()  # here, where a closed pipe can still be told apart
        return code
    except ConfigError as exc:
        print(f"zarco: configuration refused: {exc}", file=sys.stderr)
        return 2
    except PathError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        _quiet_stdout()
        return 0
    except OSError as exc:
        if exc.filename is None:
            raise
        # a path no check caught (a read-only file system, a full disk, ...): still
        # one line naming it
        print(f"{name}: {exc.filename}: {oserror_reason(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
