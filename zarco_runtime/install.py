"""What ``systemd/install.sh`` needs to know from the vessel's configuration and
from the running runtime.

``state``: whether the boat is under way, read from the running runtime (its
control socket's status: the mode and ``armed``; without an answer, its
state file: the last mission and whether it was complete).  The install never
restarts a runtime that is under way (or whose state it cannot read) unless
told to (``--force``); it can wait for it instead.  This part uses only the
standard library, so the install runs it with the system's Python before the
new runtime is installed::

    python3 zarco_runtime/install.py state --config /etc/zarco/zarco.toml --active

``unit``: the systemd unit, from the shipped one, with ``DeviceAllow=`` lines
for the devices the configuration names and no others (with the runtime's
own configuration loader: run it with the installed runtime's Python)::

    /opt/zarco/bin/python -m zarco_runtime.install unit --config /etc/zarco/zarco.toml \\
        --template systemd/zarco.service --prefix /opt/zarco

Each configured serial port (a device's ``url``, the GPS's ``corrections_url``,
a MAVLink serial ``url``) is allowed as narrowly as it can be and still work:

* a USB serial adapter (``ttyUSB*``, ``ttyACM*``, also when reached through a
  udev link such as ``/dev/zarco/gps``) by its class, ``char-ttyUSB`` or
  ``char-ttyACM``: a replugged adapter comes back with another minor number,
  and the runtime must be able to open it again without a restart;
* a fixed serial port (``/dev/ttyS0``, ``/dev/ttyAMA0``, ...) by its node only
  (never ``char-ttyS``: that class holds the virtual consoles too);
* a pseudo-terminal (``/dev/pts/N``: a bridge such as socat) as ``char-pts``;
  ``/dev/ptmx`` (making pseudo-terminals) is never allowed: only HIL makes
  them, and HIL does not run under this unit;
* a udev link whose device is not plugged in when the install runs: both USB
  serial classes (the shipped udev rules name USB adapters); run the install
  again with the devices plugged in to narrow it;
* a network device (``tcp://``): nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import socket
import sys
import tomllib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: kernel names of USB serial adapters, allowed by class (char-<class>)
USB_CLASSES = {"ttyUSB": re.compile(r"ttyUSB\d+"), "ttyACM": re.compile(r"ttyACM\d+")}
#: the line of the shipped unit after which the generated DeviceAllow lines go
DEVICE_POLICY = "DevicePolicy=closed"
#: how long to wait for the runtime's status on its control socket (s)
STATUS_TIMEOUT_S = 3.0
#: modes in which the boat is not under way
STILL = ("idle",)


# ------------------------------------------------------------------ devices


def serial_path(url: str) -> str:
    """The local device path of a device or MAVLink URL ("" for a network one):
    ``/dev/ttyUSB0``, ``serial:///dev/ttyUSB0``, ``/dev/ttyAMA0,57600``."""
    u = url.strip()
    if u.startswith("serial://"):
        u = u[len("serial://"):]
    if not u.startswith("/"):
        return ""
    return u.split(",", 1)[0]


def classify(path: str, realpath: Callable[[str], str] = os.path.realpath,
             exists: Callable[[str], bool] = os.path.exists) -> tuple[list[str], str]:
    """The ``DeviceAllow=`` values (``char-ttyUSB rw``, ``/dev/ttyS0 rw``) one
    serial device path needs, and why (see the module docstring)."""
    real = realpath(path)
    base = Path(real).name
    via = f" (at {real})" if real != path else ""
    for cls, rx in USB_CLASSES.items():
        if rx.fullmatch(base):
            return [f"char-{cls} rw"], f"a USB serial adapter{via}: its class, as a " \
                "replugged one comes back with another number"
    if real.startswith("/dev/pts/") or real == "/dev/ptmx":
        return ["char-pts rw"], f"a pseudo-terminal{via}"
    if exists(real):
        return [f"{real} rw"], f"a fixed port{via}: its node only"
    if path.startswith(("/dev/zarco/", "/dev/serial/")):
        return [f"char-{c} rw" for c in USB_CLASSES], "a udev link, not plugged in now: " \
            "the USB serial classes (install again with it plugged in to narrow this)"
    return [f"{real} rw"], "not present now: its node only"


def allow_rules(paths: Iterable[str],
                realpath: Callable[[str], str] = os.path.realpath,
                exists: Callable[[str], bool] = os.path.exists) -> list[str]:
    """``DeviceAllow=`` values for these serial device paths, each once."""
    rules: set[str] = set()
    for path in paths:
        if path:
            rules.update(classify(path, realpath, exists)[0])
    return sorted(rules)


def configured_paths(config: str) -> list[tuple[str, str]]:
    """(key, serial path) of every device the configuration drives from a local
    port, validated by the runtime's own loader (a bad file is a ConfigError)."""
    from zarco_runtime.config_file import load_runtime_config

    cfg, _mission = load_runtime_config(config)
    out = []
    for name, dev in cfg.devices.items():
        if not dev.enabled:
            continue
        out.append((f"devices.{name}.url", serial_path(dev.url)))
        if dev.corrections_url:
            out.append((f"devices.{name}.corrections_url", serial_path(dev.corrections_url)))
    if cfg.mavlink.enabled:
        urls = cfg.mavlink.url if isinstance(cfg.mavlink.url, list) else [cfg.mavlink.url]
        out += [("mavlink.url", serial_path(str(u))) for u in urls]
    return [(k, p) for k, p in out if p]


def render_unit(template: str, found: list[tuple[str, str]], prefix: str,
                source: str) -> str:
    """The unit: ``template`` with ``/opt/zarco`` at ``prefix`` and, after its
    ``DevicePolicy=closed``, the ``DeviceAllow=`` lines of the configured ports
    ``found`` ((key, path) pairs), each explained in a comment."""
    lines = template.replace("/opt/zarco", prefix).splitlines()
    if DEVICE_POLICY not in lines:
        raise ValueError(f"the unit template has no {DEVICE_POLICY} line")
    i = lines.index(DEVICE_POLICY) + 1
    gen = [f"# DeviceAllow: generated by the install from {source} (run the install "
           "again after changing a device's url)"]
    for key, path in found:
        gen.append(f"#   {key} = {path}: {classify(path)[1]}")
    rules = allow_rules(p for _, p in found)
    gen += [f"DeviceAllow={r}" for r in rules] or ["#   (no local serial port configured)"]
    return "\n".join(lines[:i] + gen + lines[i:]) + "\n"


# -------------------------------------------------------------------- state


@dataclass(slots=True)
class State:
    """What the install concludes: ``under_way`` True (do not restart), False
    (idle, or not running), None (cannot tell: treated as under way); ``text``
    says why, in words."""

    under_way: bool | None
    text: str


#: where the install makes the shore users file when the configuration names none
DEFAULT_USERS_FILE = "/etc/zarco/shore-users"


def users_file(config: str) -> str:
    """``[shore] users_file`` of a configuration file, or the default place."""
    try:
        with open(config, "rb") as fh:
            shore = tomllib.load(fh).get("shore", {})
    except (OSError, ValueError):
        return DEFAULT_USERS_FILE
    path = shore.get("users_file", "") if isinstance(shore, dict) else ""
    return str(path) if path else DEFAULT_USERS_FILE


def config_paths(config: str) -> tuple[str, str]:
    """``[supervisor] control_socket`` and ``state_file`` of a configuration
    file ("" when not set), read with the standard library."""
    with open(config, "rb") as fh:
        data = tomllib.load(fh)
    sup = data.get("supervisor", {})
    if not isinstance(sup, dict):
        return "", ""
    return str(sup.get("control_socket", "") or ""), str(sup.get("state_file", "") or "")


def query_status(path: str, timeout: float = STATUS_TIMEOUT_S) -> dict[str, Any]:
    """The runtime's status snapshot from its control socket (``zarco ctl
    status``); raises OSError or ValueError."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout)
        s.connect(path)
        s.sendall(b'{"name": "status"}\n')
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    st = json.loads(buf)
    if not isinstance(st, dict) or "mode" not in st:
        raise ValueError("no status in the reply")
    return st


def from_status(st: dict[str, Any]) -> State:
    mode = str(st.get("mode"))
    armed = bool(st.get("armed", False))
    mission = st.get("mission") or {}
    name = mission.get("name") if isinstance(mission, dict) else None
    what = f"mode {mode}" + (", armed" if armed else "") + (f", mission {name!r}"
                                                           if name else "")
    if mode in STILL and not armed:
        return State(False, f"the runtime is idle ({what})")
    return State(True, f"the boat is under way ({what})")


def from_state_file(path: str) -> State:
    """From the state file alone (the runtime does not answer): a last mission
    not complete may be running."""
    try:
        d = json.loads(Path(path).read_text(encoding="utf-8"))
        mission = d["mission"]
        name = mission.get("name", "") if isinstance(mission, dict) else ""
        complete = bool(d.get("complete", False))
    except FileNotFoundError:
        return State(None, f"the runtime does not answer and has no state file ({path})")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return State(None, f"the runtime does not answer and its state file {path} "
                     f"is unreadable ({exc})")
    if complete:
        return State(False, f"the runtime does not answer; its last mission {name!r} is "
                     "complete (state file)")
    return State(None, f"the runtime does not answer; its last mission {name!r} is not "
                 "complete (state file): it may be under way")


def runtime_state(config: str, active: bool) -> State:
    """Whether the boat is under way (see the module docstring).  ``active``: the
    service runs (systemd says so).  A runtime that answers on the configured
    control socket is asked whatever ``active`` says (one started by hand
    counts too)."""
    try:
        sock, state_file = config_paths(config)
    except FileNotFoundError:
        sock, state_file = "", ""
    except (OSError, ValueError) as exc:
        if not active:
            return State(False, "the runtime is not running")
        return State(None, f"the runtime runs and its configuration {config} is "
                     f"unreadable ({exc})")
    why = "no supervisor.control_socket configured"
    if sock:
        try:
            return from_status(query_status(sock))
        except (OSError, ValueError) as exc:
            why = f"its control socket {sock} does not answer ({exc})"
    if not active:
        return State(False, "the runtime is not running")
    if state_file:
        st = from_state_file(state_file)
        return State(st.under_way, st.text.replace("the runtime does not answer",
                                                   f"the runtime runs but {why}"))
    return State(None, f"the runtime runs but {why} and it has no state file")


# ---------------------------------------------------------------------- cli

#: exit status of ``state``: idle or not running / under way / cannot tell
EXIT_IDLE, EXIT_UNDER_WAY, EXIT_UNKNOWN = 0, 3, 4


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="install.py", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("state", help="is the boat under way? (exit 0 no, 3 yes, 4 unknown)")
    s.add_argument("--config", required=True)
    s.add_argument("--active", action="store_true", help="the service is running")
    f = sub.add_parser("users-file", help="the shore users file the configuration names")
    f.add_argument("--config", required=True)
    u = sub.add_parser("unit", help="the unit with DeviceAllow for the configured ports")
    u.add_argument("--config", required=True)
    u.add_argument("--template", required=True)
    u.add_argument("--prefix", default="/opt/zarco")
    u.add_argument("--source", default="", help="the configuration's name in the comment")
    args = ap.parse_args(argv)
    if args.cmd == "users-file":
        print(users_file(args.config))
        return 0
    if args.cmd == "state":
        st = runtime_state(args.config, args.active)
        print(st.text)
        return EXIT_IDLE if st.under_way is False else (
            EXIT_UNDER_WAY if st.under_way else EXIT_UNKNOWN)
    from zarco_core.config import ConfigError

    try:
        found = configured_paths(args.config)
    except ConfigError as exc:
        print(f"configuration refused: {exc}", file=sys.stderr)
        return 2
    for key, path in found:
        print(f"{key} = {path}: {classify(path)[1]}", file=sys.stderr)
    text = Path(args.template).read_text(encoding="utf-8")
    sys.stdout.write(render_unit(text, found, args.prefix, args.source or args.config))
    return 0


if __name__ == "__main__":
    sys.exit(main())
