"""Configuration refusals: one message naming the file, the key and the problem."""

from __future__ import annotations

from pathlib import Path

import pytest

from zarco_core.config import ConfigError
from zarco_tools.scenario import load_runtime_config, load_scenario

ROOT = Path(__file__).resolve().parents[1]
RECT = ROOT / "config" / "scenarios" / "rectangle.toml"


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "bad.toml"
    p.write_text(RECT.read_text() + "\n" + text)
    return p


def test_shipped_files_load() -> None:
    scn = load_scenario(RECT)
    assert scn.world.current.speed_mps == pytest.approx(0.2)
    assert scn.runtime.origin.lat_deg == scn.world.origin_lat_deg
    cfg, _mission = load_runtime_config(ROOT / "config" / "zarco.toml")
    assert cfg.control.rate_hz == 20.0


@pytest.mark.parametrize(
    "override,key,reason",
    [
        ("world.current.speeed_mps=0.3", "world.current.speeed_mps", "unknown key"),
        ("world.vessel.m_kg=\"heavy\"", "world.vessel.m_kg", "expected a number"),
        ("world.compass.noise_deg=-1", "world.compass.noise_deg", "must be ≥"),
        ("runtime.control.rate_hz=0", "runtime.control.rate_hz", "must be ≥"),
        ("mission.speed_mps=nan", "mission.speed_mps", "finite"),
        ("runtime.thrusters.port.f_n=[-75, 0, 0, 50, 40]", "runtime.thrusters.port",
         "has 5 points"),
        ("mission.laps=true", "mission.laps", "expected an integer"),
        ("world.gps.fix=\"rtk_perfect\"", "world.gps.fix", "must be one of"),
    ],
)
def test_override_errors_name_file_key_reason(override: str, key: str, reason: str) -> None:
    with pytest.raises(ConfigError) as ei:
        load_scenario(RECT, [override])
    err = ei.value
    assert str(RECT) in str(err)
    assert err.key.startswith(key), err
    assert reason in err.reason, err


def test_non_monotone_thruster_table(tmp_path: Path) -> None:
    p = _write(tmp_path, "[runtime.thrusters.starboard]\n"
               "u = [-100.0, -5.0, 5.0, 50.0, 100.0]\nf_n = [-75.0, 0.0, 0.0, 60.0, 50.0]\n")
    with pytest.raises(ConfigError) as ei:
        load_scenario(p)
    assert ei.value.file == str(p)
    assert ei.value.key == "runtime.thrusters.starboard.f_n"
    assert "not monotone" in ei.value.reason


def test_missing_required_and_syntax(tmp_path: Path) -> None:
    p = tmp_path / "syntax.toml"
    p.write_text("[world\n")
    with pytest.raises(ConfigError, match="TOML syntax"):
        load_scenario(p)
    with pytest.raises(ConfigError, match="file not found"):
        load_scenario(tmp_path / "nope.toml")
    p2 = tmp_path / "short.toml"
    p2.write_text("[mission]\nwaypoints = [[0.0, 0.0]]\n")
    with pytest.raises(ConfigError) as ei:
        load_scenario(p2)
    assert ei.value.key == "mission.waypoints"


def test_cli_refuses_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from zarco_runtime.cli import main

    rc = main(["sim", str(RECT), "--set", "world.current.speed_mps=9", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1
    assert "world.current.speed_mps" in err[0] and str(RECT) in err[0]
