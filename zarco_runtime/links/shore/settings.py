"""Settings of the shore link (``[shore]``).

The boat runs a zenoh peer listening on ``listen`` (multicast scouting off);
shore tools connect to it as clients.  ``auth`` says how they prove who they
are: ``usrpwd`` (zenoh user/password against ``users_file``, lines
``user:password``), ``mtls`` (TLS certificates signed by ``ca_file``; the
certificate's common name is the user) or ``none`` (no authentication:
allowed only when every endpoint is on loopback, i.e. a simulator on a
laptop).  ``operators`` may command the vessel, ``viewers`` may only watch;
anyone else is denied (zenoh access control, default deny).
"""

from __future__ import annotations

import ipaddress
import os
import re
from dataclasses import dataclass

from zarco_core.config import spec

#: link protocols the boat listens on
PROTOCOLS = ("tcp", "tls")
VESSEL_RE = re.compile(r"^[a-z0-9_-]+$")
USER_RE = re.compile(r"^[^:\s]+$")


def parse_endpoint(ep: str) -> tuple[str, str, int]:
    """``tcp/127.0.0.1:7447`` → ("tcp", "127.0.0.1", 7447); raises ValueError.

    zenoh's endpoint form is ``proto/address[?metadata][#config]``; an IPv6
    address is written in brackets (``tcp/[::1]:7447``).
    """
    proto, sep, rest = ep.partition("/")
    if not sep or proto not in PROTOCOLS:
        raise ValueError(f"{ep!r}: expected one of "
                         + ", ".join(f"{p}/HOST:PORT" for p in PROTOCOLS))
    addr = re.split(r"[?#]", rest, maxsplit=1)[0]
    m = re.fullmatch(r"\[([0-9A-Fa-f:.]+)\]:(\d+)|([^:\[\]/]+):(\d+)", addr)
    if m is None:
        raise ValueError(f"{ep!r}: expected {proto}/HOST:PORT ([IPv6]:PORT)")
    host = m.group(1) or m.group(3)
    port = int(m.group(2) or m.group(4))
    if not 1 <= port <= 65535:
        raise ValueError(f"{ep!r}: port must be 1..65535")
    return proto, host, port


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (``localhost``, 127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name: it may resolve anywhere


def read_users(path: str) -> dict[str, str]:
    """The ``users_file``: one ``user:password`` per line (blank lines and ``#``
    comments skipped); raises ValueError naming the line."""
    users: dict[str, str] = {}
    with open(path, encoding="utf-8") as fh:
        for i, raw in enumerate(fh, 1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            user, sep, pwd = line.partition(":")
            if not sep or not USER_RE.match(user) or not pwd:
                raise ValueError(f"line {i}: expected user:password")
            if user in users:
                raise ValueError(f"line {i}: user {user!r} given twice")
            users[user] = pwd
    return users


@dataclass(slots=True)
class Shore:
    """The shore link: a zenoh peer on the boat (see the module docstring)."""

    enabled: bool = spec(False, "", "run the shore link")
    vessel: str = spec("zarco", "", "this vessel's name in the key space zarco/<vessel>/... "
                       "([a-z0-9_-]+)")
    listen: list[str] = spec(lambda: ["tcp/127.0.0.1:7447"], "", "zenoh endpoints the boat "
                             "listens on (tcp/HOST:PORT, tls/HOST:PORT)")
    auth: str = spec("none", "", "how shore clients authenticate: zenoh user/password, "
                     "mutual TLS, or none (only when every endpoint is on loopback)",
                     choices=["usrpwd", "mtls", "none"])
    users_file: str = spec("", "", "usrpwd: file of user:password lines")
    operators: list[str] = spec(list, "", "users (usrpwd) or certificate common names (mtls) "
                                "that may command the vessel")
    viewers: list[str] = spec(list, "", "users or certificate common names that may only "
                              "watch (telemetry)")
    cert_file: str = spec("", "", "the boat's TLS certificate (PEM; mtls, or tls/ endpoints)")
    key_file: str = spec("", "", "the boat's TLS private key (PEM)")
    ca_file: str = spec("", "", "mtls: the CA certificate that signs operators' and viewers' "
                        "certificates (PEM)")
    state_hz: float = spec(5.0, "Hz", "rate of the state telemetry", min=0.2, max=50.0)
    rtcm_budget_bps: float = spec(65536.0, "B/s", "RTCM bytes relayed per second from "
                                  "shore (a base station sends 1-5 kB/s); the excess is "
                                  "counted and dropped", min=1024.0, max=1048576.0)
    commands_per_s: float = spec(20.0, "1/s", "commands a second from one source (the "
                                 "attachment's user), bursts of twice that; the excess is "
                                 "answered busy at once (stop is never limited)", min=1.0,
                                 max=1000.0)

    def validate(self) -> None:
        if not VESSEL_RE.match(self.vessel):
            raise ValueError(f"vessel: must match [a-z0-9_-]+, got {self.vessel!r}")
        if not self.listen:
            raise ValueError("listen: at least one endpoint (tcp/HOST:PORT)")
        eps = []
        for i, ep in enumerate(self.listen):
            try:
                eps.append(parse_endpoint(ep))
            except ValueError as exc:
                raise ValueError(f"listen[{i}]: {exc}") from None
        if not self.enabled:
            return  # the rest concerns a link that runs
        if self.auth == "none":
            for ep, (_, host, _) in zip(self.listen, eps, strict=True):
                if not is_loopback(host):
                    raise ValueError(f"auth: 'none' is allowed only when every listen "
                                     f"endpoint is on loopback, and {ep} is not; use "
                                     "usrpwd or mtls")
        tls = any(p == "tls" for p, _, _ in eps)
        if self.auth == "mtls":
            if not all(p == "tls" for p, _, _ in eps):
                raise ValueError("listen: auth = 'mtls' needs tls/ endpoints only")
            self._need_files(("cert_file", "key_file", "ca_file"), "auth = 'mtls'")
        elif tls:
            self._need_files(("cert_file", "key_file"), "a tls/ endpoint")
        both = set(self.operators) & set(self.viewers)
        if both:
            raise ValueError(f"viewers: {sorted(both)} also in operators (one role each)")
        if self.auth == "none":
            return
        if not self.operators and not self.viewers:
            raise ValueError(f"operators: with auth = {self.auth!r} nobody could use the "
                             "link: name operators and/or viewers")
        for role in ("operators", "viewers"):
            for name in getattr(self, role):
                if not USER_RE.match(name):
                    raise ValueError(f"{role}: not a user name: {name!r}")
        if self.auth == "usrpwd":
            self._need_files(("users_file",), "auth = 'usrpwd'")
            try:
                users = read_users(self.users_file)
            except (OSError, UnicodeDecodeError, ValueError) as exc:
                raise ValueError(f"users_file: {self.users_file}: {exc}") from None
            for role in ("operators", "viewers"):
                missing = [u for u in getattr(self, role) if u not in users]
                if missing:
                    raise ValueError(f"{role}: {missing} not in users_file {self.users_file}")

    def _need_files(self, keys: tuple[str, ...], why: str) -> None:
        for k in keys:
            path = getattr(self, k)
            if not path:
                raise ValueError(f"{k}: required with {why}")
            if not os.path.isfile(path):
                raise ValueError(f"{k}: {path}: no such file")
