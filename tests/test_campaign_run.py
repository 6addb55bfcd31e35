"""``zarco campaign`` runs: the same results on local processes and on a Dask
LocalCluster of two workers; a campaign killed mid-run resumes without
repeating or losing a mission, and one terminated ends its workers with it;
``zarco campaign compare`` pairs the same missions.  Small campaigns of short
missions (``scenario.max_duration_s``)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from procs import alive as running
from procs import children

from zarco_core.config import ConfigError
from zarco_runtime.cli import main as zarco
from zarco_tools.campaign.compare import compare
from zarco_tools.campaign.plots import figure_values
from zarco_tools.campaign.results import ResultsDir, read_results

ROOT = Path(__file__).resolve().parents[1]
SPEC = str(ROOT / "config" / "campaigns" / "follow.toml")
SHORT = ["--set", "scenario.max_duration_s=40"]
#: what depends on where and how fast a mission ran
RUN_FIELDS = ("wall_s", "cpu_s", "host")


def lines(out: Path) -> list[dict[str, Any]]:
    return [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]


def same(rec: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in rec.items() if k not in RUN_FIELDS}


@pytest.fixture(scope="module")
def pool(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("pool") / "a"
    assert zarco(["campaign", SPEC, "--n", "4", "--seed", "5", "--jobs", "2", "--out",
                  str(out), "--no-plots", *SHORT]) == 0
    return out


def test_results_arrive_one_line_per_mission_with_overrides_and_figures(pool: Path) -> None:
    recs = lines(pool)
    assert sorted(r["index"] for r in recs) == [0, 1, 2, 3]
    for r in recs:
        assert r["overrides"] and r["figures"]["sim_seconds"] == pytest.approx(40.0, abs=0.2)
        assert "distance_median_m" in r["figures"] and "fails" in r and "severity" in r
    summary = json.loads((pool / "summary.json").read_text())
    assert summary["missions"] == 4 and summary["campaign"]["sets"] == [
        "scenario.max_duration_s=40"]
    assert sum(g["missions"] for g in summary["by_family"].values()) == 4


def test_a_dask_local_cluster_gives_the_same_results(pool: Path, tmp_path: Path) -> None:
    from distributed import LocalCluster

    out = tmp_path / "b"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        assert zarco(["campaign", SPEC, "--n", "4", "--seed", "5", "--scheduler",
                      cluster.scheduler_address, "--out", str(out), "--no-plots",
                      *SHORT]) == 0
    a = {r["index"]: same(r) for r in lines(pool)}
    b = {r["index"]: same(r) for r in lines(out)}
    assert a == b
    hosts = {r["host"] for r in lines(out)} | {r["host"] for r in lines(pool)}
    assert len(hosts) >= 3  # ran in different processes


def test_a_killed_campaign_resumes_without_repeating_or_losing_a_mission(
        pool: Path, tmp_path: Path) -> None:
    out = tmp_path / "k"
    cmd = [sys.executable, "-m", "zarco_runtime.cli", "campaign", SPEC, "--n", "4", "--seed",
           "5", "--jobs", "1", "--out", str(out), "--no-plots",
           "--set", "scenario.max_duration_s=40", "--set", "runtime.follow.max_speed_mps=1.0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True, cwd=ROOT)
    res = out / "results.jsonl"
    deadline = time.monotonic() + 300.0
    while time.monotonic() < deadline:
        if res.exists() and res.read_text().count("\n") >= 1:
            break
        assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)
    before = res.read_text().splitlines()
    assert 1 <= len(before) < 4
    # the rerun: the same command resumes
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stderr
    assert f"{len(before)} already in" in done.stderr
    after = res.read_text().splitlines()
    assert after[: len(before)] == before  # what was done was not run again
    assert sorted(json.loads(x)["index"] for x in after) == [0, 1, 2, 3]
    # the comparison with the unchanged campaign: the same missions, paired
    c = compare(str(pool), str(out))
    assert c["paired"] == 4
    a = {r["index"]: figure_values(r) for r in lines(pool)}
    b = {r["index"]: figure_values(r) for r in lines(out)}
    d = np.array([b[k]["distance_median_m"] - a[k]["distance_median_m"] for k in range(4)])
    got = c["all"]["figures"]["distance_median_m"]
    assert got["n"] == 4
    assert got["median"] == pytest.approx(float(np.median(d)), abs=1e-4)
    assert got["mean"] == pytest.approx(float(d.mean()), abs=1e-4)
    lo, hi = got["mean_ci95"]
    assert d.min() - 1e-4 <= lo <= d.mean() + 1e-4 <= hi + 2e-4 <= d.max() + 3e-4
    pa = sum(1 for r in lines(pool) if not r["fails"] and not r["exempt"])
    assert c["all"]["checks"]["every target"]["passed_a"] == pa


def test_a_terminated_campaign_ends_its_workers_and_says_how_to_resume(
        tmp_path: Path) -> None:
    out = tmp_path / "t"
    cmd = [sys.executable, "-m", "zarco_runtime.cli", "campaign", SPEC, "--n", "6", "--seed",
           "6", "--jobs", "2", "--out", str(out), "--no-plots", *SHORT]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True, cwd=ROOT)
    try:
        res = out / "results.jsonl"
        deadline = time.monotonic() + 300.0
        while not (res.exists() and res.read_text().count("\n") >= 1):
            assert time.monotonic() < deadline
            assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
            time.sleep(0.2)
        workers = children(proc.pid)
        assert len(workers) >= 2
        proc.send_signal(signal.SIGTERM)  # the campaign alone, as `kill PID` does
        assert proc.wait(timeout=60) == 130
        err = proc.stderr.read().decode() if proc.stderr else ""
        assert "interrupted:" in err and "the same command resumes" in err
        # its workers ended with it (none left running a mission for nobody)
        deadline = time.monotonic() + 20.0
        alive = workers
        while alive and time.monotonic() < deadline:
            time.sleep(0.2)
            alive = [w for w in alive if running(w)]
        assert alive == []
        assert 1 <= res.read_text().count("\n") < 6
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)


def test_compare_refuses_different_missions(pool: Path, tmp_path: Path) -> None:
    out = tmp_path / "s6"
    assert zarco(["campaign", SPEC, "--n", "1", "--seed", "6", "--jobs", "1", "--out",
                  str(out), "--no-plots", *SHORT]) == 0
    with pytest.raises(ConfigError, match="not the same mission"):
        compare(str(pool), str(out))


def test_a_directory_of_another_campaign_is_refused(pool: Path) -> None:
    rc = zarco(["campaign", SPEC, "--n", "4", "--seed", "9", "--jobs", "1", "--out", str(pool),
                "--no-plots", *SHORT])
    assert rc == 2  # refused, nothing run or mixed
    assert len(lines(pool)) == 4


def test_a_choice_runs_the_same_missions_with_that_category_and_is_recorded(
        pool: Path, tmp_path: Path) -> None:
    # the pool's directory holds the spec's draws: another choice is another campaign
    rc = zarco(["campaign", SPEC, "--n", "4", "--seed", "5", "--jobs", "1", "--out", str(pool),
                "--no-plots", "--choice", "plan=plan", *SHORT])
    assert rc == 2 and len(lines(pool)) == 4
    out = tmp_path / "planned"
    assert zarco(["campaign", SPEC, "--n", "1", "--seed", "5", "--jobs", "1", "--out", str(out),
                  "--no-plots", "--choice", "plan=plan", *SHORT]) == 0
    (rec,) = lines(out)
    assert rec["factors"]["plan"] == "plan"
    assert any(o.startswith("mission.auv_plan=") for o in rec["overrides"])
    base = next(r for r in lines(pool) if r["index"] == 0)
    assert [o for o in rec["overrides"] if not o.startswith("mission.auv_plan=")] == [
        o for o in base["overrides"] if not o.startswith("mission.auv_plan=")]
    header = json.loads((out / "campaign.json").read_text())
    assert header["choices"] == {"plan": {"plan": 1.0}}
    assert zarco(["campaign", SPEC, "--choice", "plan=maybe", "--out", str(tmp_path / "x")]) == 2


def test_a_line_cut_short_by_a_kill_is_dropped_and_its_mission_run_again(
        tmp_path: Path) -> None:
    rec = {"index": 0, "family": "x", "overrides": [], "figures": {}, "fails": {}}
    p = tmp_path / "results.jsonl"
    p.write_text(json.dumps(rec) + "\n" + json.dumps({**rec, "index": 1})[:25])
    done, bad = read_results(p)
    assert list(done) == [0] and bad == 1
    store = ResultsDir(tmp_path, {"name": "x", "seed": 1})
    store.open()
    store.append({**rec, "index": 1})
    store.close()
    assert [json.loads(x)["index"] for x in p.read_text().splitlines()] == [0, 1]


def test_the_printed_command_reproduces_a_mission(pool: Path, tmp_path: Path) -> None:
    import shlex

    summary = json.loads((pool / "summary.json").read_text())
    rec = {r["index"]: r for r in lines(pool)}
    worst = summary["worst"][0] if summary["worst"] else None
    k = worst["index"] if worst else 0
    cmd = worst["command"] if worst else None
    if cmd is None:  # every mission passed: reproduce mission 0 from its record
        from zarco_tools.campaign.draw import Mission

        r0 = rec[0]
        cmd = Mission(0, r0["family"], r0["scenario_seed"], r0["overrides"]).command(
            str(ROOT / "config" / "scenarios" / "follow_turn.toml"),
            ["scenario.max_duration_s=40"])
    words = shlex.split(cmd)
    assert words[:2] == ["zarco", "sim"]
    report = tmp_path / "r.json"
    old = Path.cwd()
    try:
        os.chdir(ROOT)  # the command names the scenario relative to where it was printed
        assert zarco([*words[1:], "-q", "--report", str(report)]) == 0
    finally:
        os.chdir(old)
    got = json.loads(report.read_text())
    for key, v in rec[k]["figures"].items():
        assert got.get(key) == v, key
