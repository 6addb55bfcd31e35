"""Every ``zarco`` command refuses a path it cannot use with one line naming the
option, the path and the reason, and exit 2, before any long work starts: a
directory where a file is wanted, a missing directory, a read-only directory,
a file that is not UTF-8.  A recording that fails during a run ends it with
exit 1 and says so, and the summary names only files that were written.  A
reader that closes the pipe early (``| head``) gets no traceback.

Read-only directories are real: as root (who may write anywhere) a read-only
bind mount in a private mount namespace, otherwise a directory without write
permission."""

from __future__ import annotations

import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from zarco_core.paths import (
    PathError,
    read_text,
    readable_file,
    writable_dir,
    writable_file,
    write_text,
)
from zarco_runtime.cli import main

ROOT = Path(__file__).resolve().parents[1]
ZARCO = str(Path(sys.executable).with_name("zarco"))
RECT = ROOT / "config" / "scenarios" / "rectangle.toml"
VESSEL = ROOT / "config" / "zarco.toml"
CAPTURE = ROOT / "tests" / "data" / "gpsd-logs" / "hemi.log"
SHORT = ["--set", "scenario.max_duration_s=3", "-q"]


@pytest.fixture
def files(tmp_path: Path) -> Path:
    """A directory, a Latin-1 TOML file, a binary file and a valid scenario."""
    (tmp_path / "adir").mkdir()
    (tmp_path / "latin1.toml").write_bytes('name = "Leix\u00f5es"\n'.encode("latin-1"))
    (tmp_path / "binary.mcap").write_bytes(b"\xff\xfe\x00garbage")
    shutil.copy(RECT, tmp_path / "rect.toml")
    return tmp_path


def refused(capsys: pytest.CaptureFixture[str], argv: list[str], *words: str) -> str:
    """Run ``zarco argv`` in this process: exit 2, nothing on stdout (nothing ran),
    one line on stderr holding ``words``."""
    assert main(argv) == 2
    cap = capsys.readouterr()
    lines = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert len(lines) == 1, cap.err
    assert cap.out == "", cap.out
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert "Traceback" not in cap.err
    return lines[0]


# ------------------------------------------------------------- the checks


def test_the_checks_name_the_path_and_the_reason(files: Path) -> None:
    with pytest.raises(PathError, match="is a directory"):
        readable_file(files / "adir", "scenario")
    with pytest.raises(PathError, match="no such file"):
        readable_file(files / "nope.toml")
    with pytest.raises(PathError, match=r"byte 0xF5 at line 1, column 13"):
        read_text(files / "latin1.toml")
    assert read_text(files / "rect.toml") == RECT.read_text(encoding="utf-8")
    with pytest.raises(PathError, match=r"--report: .*nodir/r.json: the directory .*nodir "
                       "does not exist"):
        writable_file(files / "nodir" / "r.json", "--report")
    with pytest.raises(PathError, match="is not a directory"):
        writable_file(files / "rect.toml" / "r.json", "--report")
    with pytest.raises(PathError, match="is a directory"):
        writable_file(files / "adir", "--report")
    assert writable_file(files / "adir" / "r.json") == files / "adir" / "r.json"
    assert not (files / "adir" / "r.json").exists()  # a check writes nothing
    made = writable_dir(files / "adir" / "run", "--run-dir", create=True)
    assert made.is_dir()
    with pytest.raises(PathError, match=r"parent directory .* does not exist"):
        writable_dir(files / "nodir" / "run", "--run-dir", create=True)
    assert not (files / "nodir").exists()  # parents are never made


def test_a_result_file_is_written_whole_and_keeps_its_mode(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    write_text(out, "first\n")
    assert out.read_text() == "first\n"
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~_umask_now()
    out.chmod(0o640)
    write_text(out, "second\n")
    assert out.read_text() == "second\n" and stat.S_IMODE(out.stat().st_mode) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]  # no temporary left
    with pytest.raises(PathError, match="is a directory"):
        write_text(tmp_path, "x")


def _umask_now() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# --------------------------------------------------- each command, in-process


@pytest.mark.parametrize("cmd", ["sim", "hil"])
def test_a_scenario_that_is_not_a_readable_utf8_file(cmd: str, files: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    refused(capsys, [cmd, str(files / "adir")], str(files / "adir"), "is a directory")
    refused(capsys, [cmd, str(files / "latin1.toml")], "latin1.toml", "not UTF-8",
            "line 1, column 13")
    refused(capsys, [cmd, str(files / "missing.toml")], "missing.toml", "file not found")


def test_a_runtime_configuration_that_is_not_a_readable_utf8_file(
        files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    refused(capsys, ["run", "--config", str(files / "adir")], "configuration refused",
            "is a directory")
    refused(capsys, ["run", "--config", str(files / "latin1.toml")], "not UTF-8")
    refused(capsys, ["run", "--config", str(VESSEL), "--status",
                     str(files / "nodir" / "s.jsonl")], "zarco run: --status:",
            "does not exist")


@pytest.mark.parametrize("cmd,opt,name", [
    ("sim", "--report", "r.json"), ("sim", "--plot", "r.png"), ("sim", "--record", "r.mcap"),
    ("hil", "--report", "r.json"), ("hil", "--plot", "r.pdf")])
def test_outputs_are_checked_before_the_run(cmd: str, opt: str, name: str, files: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    scn = str(files / "rect.toml")
    refused(capsys, [cmd, scn, opt, str(files / "nodir" / name), *SHORT],
            f"zarco {cmd}: {opt}: ", "nodir", "does not exist (create it first)")
    assert not (files / "nodir").exists()
    refused(capsys, [cmd, scn, opt, str(files / "adir"), *SHORT], opt, "is a directory")
    refused(capsys, [cmd, scn, opt, str(files / "rect.toml" / name), *SHORT], opt,
            "is not a directory")


def test_a_plot_of_a_type_that_cannot_be_drawn(files: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    refused(capsys, ["sim", str(files / "rect.toml"), "--plot", str(files / "r.xyz"), *SHORT],
            "--plot", "r.xyz", "not an image type", ".png")
    refused(capsys, ["sim", str(files / "rect.toml"), "--plot", str(files / "r.png"),
                     "--report", str(files / "r.png"), *SHORT], "one file each")


def test_hil_run_dir_is_made_but_not_its_parents(files: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    refused(capsys, ["hil", str(files / "rect.toml"), "--run-dir",
                     str(files / "nodir" / "run")], "--run-dir", "does not exist")
    refused(capsys, ["hil", str(files / "rect.toml"), "--run-dir", str(files / "rect.toml")],
            "--run-dir", "is not a directory")


def test_captures_and_recordings(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    refused(capsys, ["decode", str(files / "adir")], "zarco decode: ", "is a directory")
    refused(capsys, ["replay", str(files / "adir"), "--port", "/dev/null"], "is a directory")
    refused(capsys, ["replay", str(CAPTURE), "--port", str(files / "nope")], "--port")
    for sub in (["info"], ["plot"], ["export", "--topic", "/NavState"], ["replay"], ["fix"]):
        refused(capsys, ["log", *sub, str(files / "binary.mcap")], f"zarco log {sub[0]}: ",
                "binary.mcap", "not an MCAP recording")
        refused(capsys, ["log", *sub, str(files / "adir")], "is a directory")
        refused(capsys, ["log", *sub, str(files / "none.mcap")], "no such file")


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rec") / "short.mcap"
    assert main(["sim", str(RECT), "--record", str(out), *SHORT]) == 0
    return out


def test_outputs_of_zarco_log(recording: Path, files: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    rec = str(recording)
    refused(capsys, ["log", "plot", rec, "-o", str(files / "nodir" / "x.png")], "--out",
            "does not exist")
    refused(capsys, ["log", "export", rec, "--topic", "/NavState", "-o", str(files / "adir")],
            "--out", "is a directory")
    refused(capsys, ["log", "replay", rec, "--record", str(files / "nodir" / "x.mcap")],
            "--record", "does not exist")
    (files / "taken.mcap").write_bytes(b"mine")
    refused(capsys, ["log", "fix", rec, "-o", str(files / "taken.mcap")], "already exists")
    assert (files / "taken.mcap").read_bytes() == b"mine"
    refused(capsys, ["campaign", str(ROOT / "config" / "campaigns" / "hold.toml"), "--n", "1",
                     "--out", str(files / "nodir" / "camp")], "--out", "does not exist")
    assert not (files / "nodir").exists()


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")
def test_an_export_onto_a_full_disk(recording: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """/dev/full: every write fails with ENOSPC, as on a full disk: one line, exit 1."""
    capsys.readouterr()
    assert main(["log", "export", str(recording), "--topic", "/NavState",
                 "-o", "/dev/full"]) == 1
    cap = capsys.readouterr()
    lines = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "/dev/full" in lines[0] and "Traceback" not in cap.err, cap.err
    assert os.path.exists("/dev/full")


def test_shore_console_files(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    refused(capsys, ["shore", "--config", str(files / "adir"), "stop"], "zarco shore: ",
            "is a directory")
    refused(capsys, ["shore", "--config", str(files / "latin1.toml"), "stop"], "not UTF-8")
    refused(capsys, ["shore", "--connect", "tcp/127.0.0.1:9", "mission", str(files / "adir")],
            "mission", "is a directory")
    (files / "m.toml").write_bytes(b"waypoints = [[41.0, -8.0], [41.1, -8.0]] # \xe9\n")
    refused(capsys, ["shore", "--connect", "tcp/127.0.0.1:9", "mission",
                     str(files / "m.toml")], "m.toml", "not UTF-8")


def test_a_users_file_that_cannot_be_read(files: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    users = files / "users"
    users.write_bytes("alice:p\u00e4ss\n".encode("latin-1"))
    shore = ["--set", "shore.enabled=true", "--set", 'shore.auth="usrpwd"',
             "--set", 'shore.listen=["tcp/127.0.0.1:7447"]', "--set", 'shore.operators=["alice"]']
    for bad in (users, files / "adir", files / "none"):
        refused(capsys, ["run", "--config", str(VESSEL), *shore,
                         "--set", f'shore.users_file="{bad}"'], "users_file", str(bad))


# --------------------------------------------------- real processes, real mounts


def _readonly(cmd: list[str], ro: Path) -> list[str]:
    """``cmd`` run where ``ro`` is read-only (see the module docstring)."""
    if os.geteuid() != 0:
        ro.chmod(0o555)
        return cmd
    if shutil.which("unshare") is None:  # pragma: no cover
        pytest.skip("unshare (util-linux) is needed to make a read-only mount as root")
    inner = f'mount --bind -o ro "{ro}" "{ro}" && exec "$@"'
    return ["unshare", "--mount", "--propagation", "private", "sh", "-c", inner, "sh", *cmd]


@pytest.fixture
def ro(tmp_path: Path) -> Iterator[Path]:
    d = tmp_path / "ro"
    d.mkdir()
    yield d
    d.chmod(0o755)


@pytest.mark.parametrize("opt,name", [("--report", "r.json"), ("--plot", "r.png"),
                                      ("--record", "r.mcap")])
def test_a_read_only_directory_is_refused_before_the_run(opt: str, name: str, ro: Path) -> None:
    p = subprocess.run(_readonly([ZARCO, "sim", str(RECT), opt, str(ro / name), "-q"], ro),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 2, p.stdout + p.stderr
    assert p.stdout == ""  # the run never started (its summary comes after it)
    (line,) = p.stderr.strip().splitlines()
    assert line.startswith(f"zarco sim: {opt}: {ro / name}: the directory {ro} is ")
    assert "read-only" in line or "not writable" in line
    assert list(ro.iterdir()) == []


def test_run_status_file_in_a_read_only_directory(ro: Path) -> None:
    p = subprocess.run(_readonly([ZARCO, "run", "--config", str(VESSEL), "--status",
                                  str(ro / "s.jsonl")], ro),
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "--status" in p.stderr and "Traceback" not in p.stderr


def test_a_recording_that_fails_during_the_run_ends_it(tmp_path: Path) -> None:
    """The recording's disk fills up during the run (a 256 KiB file system as
    root; otherwise the free-space floor stops the recorder the same way): the
    run stops there, exit 1, one line says why, and the summary never claims a
    complete recording."""
    out = tmp_path / "small"
    out.mkdir()
    rec = out / "r.mcap"
    cmd = [ZARCO, "sim", str(RECT), "-q", "--record", str(rec), "--report",
           str(tmp_path / "r.json")]
    if os.geteuid() == 0 and shutil.which("unshare"):
        inner = f'mount -t tmpfs -o size=256k none "{out}" && exec "$@"'
        cmd = ["unshare", "--mount", "--propagation", "private", "sh", "-c", inner, "sh",
               *cmd, "--set", "runtime.record.min_free_mb=0"]
        why = "recording failed"
    else:
        cmd += ["--set", "runtime.record.min_free_mb=1e9"]
        why = "below the floor"
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert p.returncode == 1, p.stdout + p.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["stop"].startswith("recording failed at ")
    assert report["sim_seconds"] < 300.0  # ended there, not at the mission's end (308 s)
    err = [ln for ln in p.stderr.splitlines() if ln.startswith("zarco sim: ")]
    assert len(err) == 1 and err[0].startswith(f"zarco sim: --record: {rec}: recording "
                                               "failed: ") and why in p.stderr, p.stderr
    named = [ln for ln in p.stdout.splitlines() if ln.startswith("record:")]
    assert all("incomplete" in ln for ln in named), named
    assert f"report: {tmp_path / 'r.json'}" in p.stdout


def test_summary_names_only_what_was_written(tmp_path: Path) -> None:
    rec, rep = tmp_path / "r.mcap", tmp_path / "r.json"
    p = subprocess.run([ZARCO, "sim", str(RECT), *SHORT, "--record", str(rec), "--report",
                        str(rep)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert f"record: {rec}\n" in p.stdout and f"report: {rep}\n" in p.stdout
    assert rec.stat().st_size > 0 and json.loads(rep.read_text())["scenario"] == "rectangle"
    assert [x.name for x in tmp_path.iterdir() if x.name.startswith(".")] == []  # no temp file


# ------------------------------------------------------------ closed pipes


def _into_a_closed_pipe(cmd: list[str]) -> subprocess.CompletedProcess[str]:
    """Run ``cmd`` with its standard output a pipe whose reader has gone (the
    moment ``head`` has read its lines)."""
    r, w = os.pipe()
    os.close(r)
    try:
        return subprocess.run(cmd, stdout=w, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(w)


def test_a_closed_pipe_is_quiet(recording: Path) -> None:
    for cmd in ([ZARCO, "decode", str(CAPTURE)], [ZARCO, "log", "info", str(recording)],
                [ZARCO, "log", "export", str(recording), "--topic", "/NavState"]):
        p = _into_a_closed_pipe(cmd)
        # (decode's refusals of the capture's sentences go to stderr as usual)
        assert p.returncode == 0, (cmd, p.stderr)
        assert "Traceback" not in p.stderr and "Broken pipe" not in p.stderr, p.stderr
        assert "BrokenPipe" not in p.stderr and "Exception ignored" not in p.stderr


def _listening(path: Path) -> bool:
    with socket.socket(socket.AF_UNIX) as s:
        try:
            s.connect(str(path))
        except OSError:
            return False
    return True


def test_ctl_status_into_a_closed_pipe(tmp_path: Path) -> None:
    sock = tmp_path / "control.sock"
    boat = subprocess.Popen([ZARCO, "sim", str(ROOT / "config" / "scenarios" / "hold.toml"),
                             "--realtime", "-q", "--set",
                             f'runtime.supervisor.control_socket="{sock}"'],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 120.0
        while time.monotonic() < end and boat.poll() is None and not _listening(sock):
            time.sleep(0.1)
        assert boat.poll() is None and _listening(sock), boat.stderr.read() \
            if boat.stderr else ""
        p = _into_a_closed_pipe([ZARCO, "ctl", "--socket", str(sock), "status"])
        assert p.returncode == 0 and p.stderr == "", p.stderr
        # and read whole, the same command prints the status
        full = subprocess.run([ZARCO, "ctl", "--socket", str(sock), "status"],
                              capture_output=True, text=True, timeout=60)
        assert full.returncode == 0 and "mode" in json.loads(full.stdout), full.stdout
    finally:
        boat.terminate()
        boat.wait(timeout=60)
