"""The shore side of the zenoh protocol: connections, credentials, telemetry, commands.

A :class:`ShoreClient` holds one zenoh client session per boat endpoint (a
zenoh client connects to one peer at a time; a fleet is several), keeps the
latest telemetry of every vessel it hears (``zarco/*/state`` and so on),
sends commands as queries and returns the boat's reply, publishes the
operator heartbeat and relays RTCM3 corrections.  It is thread-safe: zenoh
calls its callbacks on its own threads.

Credentials never come from the command line: a console configuration file
(TOML) and/or the environment:

=======================  ====================================================
``connect``              boat endpoints (``tcp/HOST:PORT``, ``tls/HOST:PORT``);
                         env ``ZARCO_SHORE_CONNECT`` (comma-separated), or
                         ``--connect`` (an address is no secret)
``credentials_file``     a file with one line ``user:password`` (usrpwd);
                         env ``ZARCO_SHORE_CREDENTIALS``, or
                         ``ZARCO_SHORE_USER`` + ``ZARCO_SHORE_PASSWORD``
``cert_file``,           the operator's certificate and key (mtls); env
``key_file``             ``ZARCO_SHORE_CERT``, ``ZARCO_SHORE_KEY``
``ca_file``              the CA that signed the boat's certificate (tls/
                         endpoints); env ``ZARCO_SHORE_CA``
``user``                 the name the console gives in commands and
                         heartbeats (default: the credentials' user, or the
                         certificate's common name); env ``ZARCO_SHORE_USER``
``vessel``               the vessel commands go to when several are heard;
                         env ``ZARCO_SHORE_VESSEL``, or ``--vessel``
``[[endpoints]]``        per-endpoint tables (``endpoint`` and any of the
                         keys above) for a fleet with different credentials
=======================  ====================================================
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import stat
import threading
import time
import tomllib
import uuid
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from zarco_core.paths import PathError, oserror_reason, read_text
from zarco_runtime.links.shore.settings import parse_endpoint
from zarco_runtime.links.shore.zenoh_config import TELEMETRY, client_config

log = logging.getLogger("zarco.shore.client")
DEFAULT_CONFIG = Path.home() / ".config" / "zarco" / "shore.toml"
_ids = itertools.count(1)


class ShoreError(Exception):
    """A console problem a person can act on (configuration, connection)."""


@dataclass(slots=True)
class Credentials:
    """How to reach and authenticate to one boat endpoint."""

    endpoint: str
    user: str = ""
    password: str = ""
    cert_file: str = ""
    key_file: str = ""
    ca_file: str = ""

    def zenoh(self) -> dict[str, Any]:
        return client_config(self.endpoint, user=self.user if self.password else "",
                             password=self.password, cert_file=self.cert_file,
                             key_file=self.key_file, ca_file=self.ca_file)


@dataclass(slots=True)
class ConsoleConfig:
    """What the console needs: its endpoints with their credentials, its name."""

    endpoints: list[Credentials] = field(default_factory=list)
    user: str = ""
    vessel: str = ""
    heartbeat_hz: float = 1.0
    ntrip_user: str = ""
    ntrip_password: str = ""


def _read_credentials_file(path: str) -> tuple[str, str]:
    p = Path(path).expanduser()
    try:
        text = read_text(p)
        mode = p.stat().st_mode
    except PathError as exc:
        raise ShoreError(f"credentials file {path}: {exc.reason}") from None
    except OSError as exc:
        raise ShoreError(f"credentials file {path}: {oserror_reason(exc)}") from None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        log.warning("credentials file %s is readable by others (chmod 600 it)", path)
    lines = [ln.strip() for ln in text.splitlines()
             if ln.strip() and not ln.strip().startswith("#")]
    if len(lines) != 1 or ":" not in lines[0]:
        raise ShoreError(f"credentials file {path}: expected one line user:password")
    user, _, pwd = lines[0].partition(":")
    return user, pwd


def _cert_common_name(path: str) -> str:
    try:
        from cryptography import x509
        from cryptography.x509.oid import NameOID

        cert = x509.load_pem_x509_certificate(Path(path).expanduser().read_bytes())
        names = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
        return str(names[0].value) if names else ""
    except Exception:  # no cryptography, or not a PEM certificate: the user says
        return ""


def _apply(c: Credentials, d: dict[str, Any], where: str) -> Credentials:
    known = {"endpoint", "credentials_file", "cert_file", "key_file", "ca_file", "user"}
    for k in d:
        if k not in known:
            raise ShoreError(f"{where}: unknown key {k!r}")
    if "credentials_file" in d:
        user, pwd = _read_credentials_file(str(d["credentials_file"]))
        c = replace(c, user=user, password=pwd)
    for k in ("cert_file", "key_file", "ca_file"):
        if k in d:
            setattr(c, k, str(Path(str(d[k])).expanduser()))
    if "user" in d and not c.password:
        c.user = str(d["user"])
    return c


def load_console_config(path: str | None, connect: list[str], vessel: str = "",
                        env: dict[str, str] | None = None) -> ConsoleConfig:
    """The console's configuration: ``path`` (or ``ZARCO_SHORE_CONFIG``, or
    ``~/.config/zarco/shore.toml`` if it exists), then the environment, then
    ``connect`` / ``vessel`` from the command line."""
    env = dict(os.environ if env is None else env)
    file = path or env.get("ZARCO_SHORE_CONFIG") or (
        str(DEFAULT_CONFIG) if DEFAULT_CONFIG.exists() else "")
    data: dict[str, Any] = {}
    if file:
        try:
            data = tomllib.loads(read_text(file))
        except PathError as exc:
            raise ShoreError(str(exc)) from None
        except tomllib.TOMLDecodeError as exc:
            raise ShoreError(f"{file}: TOML syntax error: {exc}") from None
    tables = data.pop("endpoints", [])
    ntrip = data.pop("ntrip", {})
    top_keys = {"connect", "vessel", "heartbeat_hz"}
    base_d = {k: v for k, v in data.items() if k not in top_keys}
    base = _apply(Credentials(""), base_d, file or "config")
    # the environment overrides the file
    if env.get("ZARCO_SHORE_CREDENTIALS"):
        base = _apply(base, {"credentials_file": env["ZARCO_SHORE_CREDENTIALS"]}, "env")
    if env.get("ZARCO_SHORE_PASSWORD"):
        base.user = env.get("ZARCO_SHORE_USER", base.user)
        base.password = env["ZARCO_SHORE_PASSWORD"]
    for k, var in (("cert_file", "ZARCO_SHORE_CERT"), ("key_file", "ZARCO_SHORE_KEY"),
                   ("ca_file", "ZARCO_SHORE_CA")):
        if env.get(var):
            setattr(base, k, env[var])
    eps: list[str] = list(connect) or [e.strip() for e in
                                        env.get("ZARCO_SHORE_CONNECT", "").split(",")
                                        if e.strip()] or list(data.get("connect", []))
    creds = [replace(base, endpoint=e) for e in eps]
    for i, t in enumerate(tables):
        if not isinstance(t, dict) or "endpoint" not in t:
            raise ShoreError(f"{file}: endpoints[{i}]: needs an endpoint")
        creds.append(_apply(replace(base, endpoint=str(t["endpoint"])), t,
                            f"{file}: endpoints[{i}]"))
    if not creds:
        raise ShoreError("no boat to connect to: give --connect tcp/HOST:PORT, "
                         "ZARCO_SHORE_CONNECT, or connect = [...] in the console "
                         f"configuration ({DEFAULT_CONFIG})")
    for c in creds:
        try:
            parse_endpoint(c.endpoint)
        except ValueError as exc:
            raise ShoreError(f"endpoint {exc}") from None
        if c.cert_file and not c.key_file:
            raise ShoreError(f"{c.endpoint}: a certificate needs its key_file")
    user = env.get("ZARCO_SHORE_USER") or str(data.get("user", "")) or base.user
    if not user and base.cert_file:
        user = _cert_common_name(base.cert_file)
    nu, npw = "", ""
    if isinstance(ntrip, dict) and ntrip.get("credentials_file"):
        nu, npw = _read_credentials_file(str(ntrip["credentials_file"]))
    nu = env.get("ZARCO_NTRIP_USER", nu)
    npw = env.get("ZARCO_NTRIP_PASSWORD", npw)
    return ConsoleConfig(creds, user or os.environ.get("USER", "operator"),
                         vessel or env.get("ZARCO_SHORE_VESSEL", "")
                         or str(data.get("vessel", "")),
                         float(data.get("heartbeat_hz", 1.0)), nu, npw)


# ------------------------------------------------------------------ client


@dataclass(slots=True)
class VesselView:
    """The latest telemetry of one vessel, and when it arrived (local monotonic s)."""

    name: str
    state: dict[str, Any] = field(default_factory=dict)
    health: dict[str, Any] = field(default_factory=dict)
    auv: dict[str, Any] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    map: dict[str, Any] = field(default_factory=dict)
    received: dict[str, float] = field(default_factory=dict)
    endpoint: str = ""

    def age_s(self, kind: str = "state", now: float | None = None) -> float | None:
        t = self.received.get(kind)
        return None if t is None else (time.monotonic() if now is None else now) - t


@dataclass(slots=True)
class Reply:
    """The boat's reply to a command (``ok``, ``id``, ``mode``, ``reason``)."""

    vessel: str
    ok: bool
    id: Any
    mode: Any
    reason: str
    rtt_s: float
    raw: dict[str, Any]


class ShoreClient:
    """zenoh client sessions to one or several boats (see the module docstring)."""

    #: events kept per vessel
    EVENTS = 50

    def __init__(self, config: ConsoleConfig, on_sample: Any = None) -> None:
        self.config = config
        self.sessions: list[tuple[Credentials, Any]] = []
        self.vessels: dict[str, VesselView] = {}
        self.lock = threading.Lock()
        self.on_sample = on_sample
        self.received = 0
        self._hb_stop = threading.Event()
        self._hb_thread: threading.Thread | None = None
        self._hb_vessels: set[str] | None = None
        self.client_id = uuid.uuid4().hex[:8]
        #: UTC time of the last heartbeat published (None: none yet)
        self.last_heartbeat: float | None = None

    # --------------------------------------------------------- connection

    def connect(self, subscribe: bool = True) -> list[str]:
        """Open a session per endpoint; returns the endpoints that failed (with why)."""
        import zenoh

        failed: list[str] = []
        for cred in self.config.endpoints:
            try:
                session = zenoh.open(zenoh.Config.from_json5(json.dumps(cred.zenoh())))
            except zenoh.ZError as exc:
                failed.append(f"{cred.endpoint}: cannot connect (no boat there, or "
                              f"credentials refused): {str(exc).split(' at ')[0]}")
                continue
            self.sessions.append((cred, session))
            if subscribe:
                for kind in TELEMETRY:
                    session.declare_subscriber(f"zarco/*/{kind}",
                                               self._on_telemetry(kind, cred.endpoint))
        return failed

    def close(self) -> None:
        self.stop_heartbeat()
        sessions, self.sessions = self.sessions, []
        for _, s in sessions:
            try:
                s.close()
            except Exception as exc:  # closing a session that already failed
                log.debug("close: %s", exc)

    def __enter__(self) -> ShoreClient:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    # ---------------------------------------------------------- telemetry

    def _on_telemetry(self, kind: str, endpoint: str) -> Any:
        def cb(sample: Any) -> None:
            key = str(sample.key_expr)
            parts = key.split("/")
            if len(parts) != 3:
                return
            try:
                obj = json.loads(sample.payload.to_bytes())
            except ValueError:
                return
            if not isinstance(obj, dict):
                return
            now = time.monotonic()
            with self.lock:
                self.received += 1
                v = self.vessels.get(parts[1])
                if v is None:
                    v = self.vessels[parts[1]] = VesselView(parts[1], endpoint=endpoint)
                v.received[kind] = now
                if kind == "event":
                    v.events.append(obj)
                    del v.events[:-self.EVENTS]
                else:
                    setattr(v, kind, obj)
            if self.on_sample is not None:
                self.on_sample(parts[1], kind, obj, now)
        return cb

    def snapshot(self) -> dict[str, VesselView]:
        with self.lock:
            return {k: replace(v, events=list(v.events), received=dict(v.received))
                    for k, v in self.vessels.items()}

    def wait_vessels(self, timeout_s: float, want: str = "") -> list[str]:
        """Vessels heard within ``timeout_s`` (returns as soon as ``want`` is, or,
        without ``want``, after the first is heard and a short settle)."""
        deadline = time.monotonic() + timeout_s
        first: float | None = None
        while time.monotonic() < deadline:
            with self.lock:
                names = sorted(self.vessels)
            if want and want in names:
                return names
            if names and not want:
                first = first or time.monotonic()
                if time.monotonic() - first > 0.3:
                    return names
            time.sleep(0.02)
        with self.lock:
            return sorted(self.vessels)

    def resolve_vessel(self, timeout_s: float = 2.0) -> str:
        """The vessel to command: the configured one, or the only one heard."""
        if self.config.vessel:
            return self.config.vessel
        names = self.wait_vessels(timeout_s)
        if len(names) == 1:
            return names[0]
        if not names:
            raise ShoreError("no vessel heard on " + ", ".join(
                c.endpoint for c, _ in self.sessions) + "; give --vessel NAME")
        raise ShoreError(f"several vessels heard ({', '.join(names)}): give --vessel NAME")

    # ----------------------------------------------------------- commands

    def command(self, vessel: str, name: str, args: dict[str, Any] | None = None,
                timeout_s: float = 3.0) -> list[Reply]:
        """Send ``cmd/<name>`` to ``vessel``; the replies (one per boat of that
        name: normally exactly one; none if not authorised or unreachable)."""
        payload = json.dumps(args or {})
        cid = f"{self.config.user}-{self.client_id}-{next(_ids)}"
        att = json.dumps({"user": self.config.user, "id": cid})
        out: list[Reply] = []
        with self.lock:
            seen = self.vessels.get(vessel)
        sessions = [s for c, s in self.sessions if seen is None or c.endpoint == seen.endpoint]
        for s in sessions:
            t0 = time.monotonic()
            for r in s.get(f"zarco/{vessel}/cmd/{name}", payload=payload, attachment=att,
                           timeout=timeout_s):
                rtt = time.monotonic() - t0
                body = r.ok.payload.to_bytes() if r.ok is not None else r.err.payload.to_bytes()
                try:
                    d = json.loads(body)
                except ValueError:
                    d = {"ok": False, "reason": body.decode("utf-8", "replace")}
                if not isinstance(d, dict):
                    d = {"ok": False, "reason": str(d)}
                out.append(Reply(vessel, bool(d.get("ok")) and r.ok is not None, d.get("id"),
                                 d.get("mode"), str(d.get("reason") or ""), rtt, d))
        return out

    # ----------------------------------------------- heartbeat, corrections

    def heartbeat(self, vessels: list[str] | None = None) -> None:
        """Publish one operator heartbeat to ``vessels`` (default: every one heard)."""
        if vessels is None:
            with self.lock:
                vessels = sorted(self.vessels)
        t = time.time()
        msg = json.dumps({"t": round(t, 3), "user": self.config.user})
        for v in vessels:
            for _, s in self._sessions_for(v):
                s.put(f"zarco/{v}/operator", msg)
        self.last_heartbeat = t

    def _sessions_for(self, vessel: str) -> list[tuple[Credentials, Any]]:
        with self.lock:
            seen = self.vessels.get(vessel)
        return [(c, s) for c, s in self.sessions if seen is None or c.endpoint == seen.endpoint]

    def start_heartbeat(self, vessels: list[str] | None = None) -> None:
        """Publish the heartbeat at ``heartbeat_hz`` from a thread until :meth:`close`."""
        self._hb_vessels = set(vessels) if vessels is not None else None
        period = 1.0 / max(0.2, self.config.heartbeat_hz)

        def loop() -> None:
            while not self._hb_stop.is_set():
                try:
                    self.heartbeat(sorted(self._hb_vessels) if self._hb_vessels is not None
                                   else None)
                except Exception as exc:  # a session closing under us
                    log.debug("heartbeat: %s", exc)
                self._hb_stop.wait(period)

        self._hb_stop.clear()
        self._hb_thread = threading.Thread(target=loop, name="zarco-shore-heartbeat",
                                           daemon=True)
        self._hb_thread.start()

    def stop_heartbeat(self) -> None:
        self._hb_stop.set()
        t, self._hb_thread = self._hb_thread, None
        if t is not None:
            t.join(timeout=2.0)

    def rtcm(self, vessel: str, data: bytes) -> None:
        """Relay RTCM3 bytes to ``vessel``'s GPS receiver."""
        for _, s in self._sessions_for(vessel):
            s.put(f"zarco/{vessel}/rtcm", data)
