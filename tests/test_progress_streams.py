"""The progress lines of long jobs (a campaign, a replay, a simulation) go to
the stderr of when they run, not to the one of when their module was first
imported: a program (or a test harness) that swaps stderr, or closes the one
it had, must not see a later job fail on a closed file or print nowhere."""

from __future__ import annotations

import io
import sys

import pytest

from zarco_tools.campaign.cli import Progress as CampaignProgress
from zarco_tools.replay import Progress as ReplayProgress
from zarco_tools.simulation import StatusLine


def test_progress_goes_to_the_stderr_of_when_it_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    gone = io.StringIO()
    monkeypatch.setattr(sys, "stderr", gone)
    gone.close()  # what a harness does with the stderr it handed out
    now = io.StringIO()
    monkeypatch.setattr(sys, "stderr", now)
    CampaignProgress(2, 0)({"index": 0, "family": "lawnmower", "severity": 1.0, "fails": {}})
    ReplayProgress(10, 5.0)(3, 1.5, force=True)
    StatusLine()(12.0, 100.0, 0, 2)
    out = now.getvalue().splitlines()
    assert out[0].startswith("[    1/2") and out[0].endswith("ok")
    assert out[1].startswith("replay: 3/10 lines")
    assert out[2].startswith("sim    12.0 s  leg 1/2")
