"""Helpers for the shore-link tests and benchmark: simulated boats in their own
processes (``zarco sim SCENARIO --realtime`` with the shore link on), free
loopback ports, users files and test certificates."""

from __future__ import annotations

import contextlib
import datetime as dt
import ipaddress
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from zarco_tools.shore.client import ConsoleConfig, Credentials, ShoreClient

ROOT = Path(__file__).resolve().parents[1]
RECT = ROOT / "config" / "scenarios" / "rectangle.toml"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def write_users(path: Path, users: dict[str, str]) -> Path:
    path.write_text("".join(f"{u}:{p}\n" for u, p in users.items()))
    path.chmod(0o600)
    return path


def write_credentials(path: Path, user: str, password: str) -> Path:
    path.write_text(f"{user}:{password}\n")
    path.chmod(0o600)
    return path


class Pki:
    """A throw-away CA and certificates (EC P-256) made with ``cryptography``."""

    def __init__(self, root: Path, name: str = "zarco-test-ca") -> None:
        from cryptography import x509
        from cryptography.hazmat.primitives import hashes
        from cryptography.hazmat.primitives.asymmetric import ec

        self.root = root
        root.mkdir(parents=True, exist_ok=True)
        self.key = ec.generate_private_key(ec.SECP256R1())
        now = dt.datetime.now(dt.UTC)
        self.cert = (
            x509.CertificateBuilder().subject_name(self._name(name))
            .issuer_name(self._name(name)).public_key(self.key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=1))
            .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
            .add_extension(x509.KeyUsage(True, False, False, False, False, True, True, False,
                                         False), critical=True)
            .sign(self.key, hashes.SHA256()))
        self.ca_file = self._write(f"{name}.pem", self._pem(self.cert))

    @staticmethod
    def _name(cn: str) -> Any:
        from cryptography import x509
        from cryptography.x509.oid import NameOID

        return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])

    @staticmethod
    def _pem(obj: Any) -> bytes:
        from cryptography.hazmat.primitives import serialization

        if hasattr(obj, "public_bytes"):
            return bytes(obj.public_bytes(serialization.Encoding.PEM))
        return bytes(obj.private_bytes(serialization.Encoding.PEM,
                                       serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))

    def _write(self, name: str, data: bytes) -> str:
        p = self.root / name
        p.write_bytes(data)
        p.chmod(0o600)
        return str(p)

    def issue(self, cn: str) -> tuple[str, str]:
        """A certificate for ``cn`` (valid for localhost / 127.0.0.1): (cert, key) files."""
        from cryptography import x509
        from cryptography.hazmat.primitives import hashes
        from cryptography.hazmat.primitives.asymmetric import ec

        key = ec.generate_private_key(ec.SECP256R1())
        now = dt.datetime.now(dt.UTC)
        cert = (
            x509.CertificateBuilder().subject_name(self._name(cn))
            .issuer_name(self.cert.subject).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=1))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.SubjectAlternativeName(
                [x509.DNSName("localhost"),
                 x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), critical=False)
            .sign(self.key, hashes.SHA256()))
        return (self._write(f"{cn}.pem", self._pem(cert)),
                self._write(f"{cn}.key", self._pem(key)))


class Boat:
    """``zarco sim SCENARIO --realtime`` with the shore link, in its own process."""

    def __init__(self, sets: list[str], scenario: Path = RECT, log: Path | None = None,
                 extra_args: list[str] | None = None) -> None:
        self.args = [sys.executable, "-m", "zarco_runtime.cli", "sim", str(scenario),
                     "--realtime", "-q", "--set", "runtime.shore.enabled=true"]
        for s in sets:
            self.args += ["--set", s]
        self.args += extra_args or []
        self.log = log
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> Boat:
        out: Any = self.log.open("wb") if self.log is not None else subprocess.DEVNULL
        self.proc = subprocess.Popen(self.args, stdout=out, stderr=subprocess.STDOUT,
                                     cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        return self

    def stop(self, timeout_s: float = 15.0) -> int:
        p = self.proc
        if p is None:
            return 0
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout_s)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        return int(p.returncode)

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid


@contextlib.contextmanager
def boats(*bs: Boat) -> Iterator[tuple[Boat, ...]]:
    try:
        for b in bs:
            b.start()
        yield bs
    finally:
        for b in bs:
            b.stop()


def connect_when_up(make: Any, timeout_s: float = 30.0) -> Any:
    """Call ``make()`` (which raises until the boat listens) until it returns."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return make()
        except Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def shore(*args: str, env: dict[str, str] | None = None, timeout: float = 30.0
          ) -> subprocess.CompletedProcess[str]:
    """``zarco shore ARGS`` as an operator types it."""
    return subprocess.run([sys.executable, "-m", "zarco_runtime.cli", "shore", *args],
                          capture_output=True, text=True, cwd=ROOT, timeout=timeout,
                          env={**os.environ, **(env or {})})


def observer(eps: list[str], want: list[str], timeout_s: float = 30.0) -> ShoreClient:
    """A client of every endpoint that has heard every vessel in ``want``."""
    deadline = time.monotonic() + timeout_s
    while True:
        c = ShoreClient(ConsoleConfig([Credentials(e) for e in eps], user="observer"))
        if not c.connect() and set(want) <= set(c.wait_vessels(5.0, want[-1])):
            return c
        c.close()
        if time.monotonic() > deadline:
            raise AssertionError(f"never heard {want} on {eps}")
        time.sleep(0.3)


def acks(c: ShoreClient, vessel: str) -> list[str]:
    """The texts of the acknowledgement events ``c`` heard from ``vessel``."""
    v = c.snapshot().get(vessel)
    return [e["text"] for e in (v.events if v else []) if e.get("kind") == "ack"]


def wait_ack(c: ShoreClient, vessel: str, text: str, timeout_s: float = 10.0) -> None:
    """Until ``c`` heard an acknowledgement containing ``text`` from ``vessel``
    (the event may follow the state that shows the command's effect)."""
    deadline = time.monotonic() + timeout_s
    while not any(text in a for a in acks(c, vessel)):
        assert time.monotonic() < deadline, f"no acknowledgement {text!r}: {acks(c, vessel)}"
        time.sleep(0.05)
