"""Drawing a campaign's missions: mission ``index`` of campaign ``seed`` is a
pure function of (spec, seed, index), whatever else is drawn and wherever it
runs.

A mission is a set of ``--set`` overrides of the spec's base scenario and a
scenario seed, so ``zarco sim`` reproduces it (:meth:`Mission.command`), with
the drawn factors beside them for the tables and plots.  The drawers
(:func:`drawer`) know what each kind of campaign draws, its targets and how a
report is judged.
"""

from __future__ import annotations

import contextlib
import functools
import json
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

if TYPE_CHECKING:
    from zarco_tools.campaign.spec import CampaignSpec, Family


@dataclass(slots=True)
class Mission:
    """One drawn mission: its ``index`` in the campaign, ``family``, the seed of
    its scenario, the ``--set`` overrides of the base scenario, and the drawn
    ``factors`` (numbers and categories, for the tables and plots)."""

    index: int
    family: str
    scenario_seed: int
    overrides: list[str] = field(default_factory=list)
    factors: dict[str, Any] = field(default_factory=dict)

    def command(self, scenario_file: str, sets: list[str] | None = None) -> str:
        """The ``zarco sim`` command line that runs this mission alone."""
        path = Path(scenario_file)
        with contextlib.suppress(ValueError):
            path = path.resolve().relative_to(Path.cwd())
        words = ["zarco", "sim", str(path), "--seed", str(self.scenario_seed)]
        for o in [*self.overrides, *(sets or [])]:
            words += ["--set", o]
        return " ".join(shlex.quote(w) for w in words)


@dataclass(frozen=True, slots=True)
class Judgement:
    """A mission's report against its targets: ``fails`` per target (short
    reasons), ``exempt`` per target where physics or observability forbids
    it (the reason with the figure: not counted as a miss), ``severity`` (the
    largest figure/target ratio; ≤ 1 when every target is met), per
    manoeuvre of the report whether it met its targets (``turns_ok``), and
    ``left_out``: physics forbids what the mission is for (no boat could meet
    its targets), so it is left out of "every target" — an exemption for
    observability (a sound speed no timing can tell) is not a reason to leave
    the rest of the mission unjudged."""

    fails: dict[str, list[str]]
    exempt: dict[str, str]
    severity: float
    turns_ok: tuple[bool, ...] = ()
    left_out: bool = False


class Drawer(Protocol):
    """What a kind of campaign draws and how it judges a mission."""

    kind: ClassVar[str]
    #: target names and what the spec's ``[targets]`` must give
    targets: ClassVar[tuple[str, ...]]
    #: the table rows a mission is judged on (a target group each)
    checks: ClassVar[tuple[str, ...]]
    #: range names and the bounds a spec may draw them within
    ranges: ClassVar[dict[str, tuple[float, float]]]
    #: category names and their values
    choices: ClassVar[dict[str, tuple[str, ...]]]
    #: family settings and their values
    settings: ClassVar[dict[str, tuple[Any, ...]]]
    #: report keys kept per mission
    figures: ClassVar[tuple[str, ...]]

    def required_ranges(self, spec: CampaignSpec, fam: Family) -> list[str]: ...

    def required_choices(self, spec: CampaignSpec, fam: Family) -> list[str]: ...

    def check(self, spec: CampaignSpec) -> None: ...

    def draw(self, d: Draw) -> None: ...

    def judge(self, spec: CampaignSpec, factors: dict[str, Any], report: dict[str, Any]
              ) -> Judgement: ...


class Draw:
    """The state of one mission's draw: uniform numbers from the family's
    ranges, weighted categories, the overrides and factors it sets."""

    def __init__(self, spec: CampaignSpec, fam: Family, rng: np.random.Generator) -> None:
        self.spec = spec
        self.fam = fam
        self.rng = rng
        self.sets: dict[str, Any] = {}
        self.factors: dict[str, Any] = {"family": fam.name}

    def u(self, name: str, nd: int = 3) -> float:
        """A uniform number from the range ``name``, rounded to ``nd`` decimals."""
        lo, hi = self.spec.range(self.fam, name)
        return round(float(self.rng.uniform(lo, hi)), nd)

    def integer(self, name: str) -> int:
        """A uniform integer from the range ``name`` (both ends included)."""
        lo, hi = self.spec.range(self.fam, name)
        return int(self.rng.integers(round(lo), round(hi) + 1))

    def pick(self, name: str) -> str:
        """A category ``name`` drawn by its weights."""
        w = self.spec.choice(self.fam, name)
        names = list(w)
        p = np.array([w[n] for n in names])
        return names[int(self.rng.choice(len(names), p=p / p.sum()))]

    def setting(self, name: str, default: Any = None) -> Any:
        return self.fam.settings.get(name, default)


def toml_value(v: Any) -> str:
    """``v`` as a TOML literal for ``--set``."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, (int, np.integer)):
        return repr(int(v))
    raise TypeError(f"no TOML literal for {v!r}")


def pick_family(spec: CampaignSpec, rng: np.random.Generator) -> Family:
    w = np.array([f.weight for f in spec.families])
    return spec.families[int(rng.choice(len(w), p=w / w.sum()))]


def scenario_seed(seed: int, index: int) -> int:
    """The scenario seed of mission ``index`` of campaign ``seed`` (32 bits)."""
    return int(np.random.SeedSequence([seed, index, 0x5EED]).generate_state(1)[0])


def draw_mission(spec: CampaignSpec, seed: int, index: int) -> Mission:
    """Mission ``index`` of campaign ``seed`` (independent of how many are drawn)."""
    rng = np.random.default_rng([seed, index])
    fam = pick_family(spec, rng)
    d = Draw(spec, fam, rng)
    drawer(spec.kind).draw(d)
    d.sets.setdefault("scenario.name", f"{spec.name}-{seed}-{index}")
    return Mission(index, fam.name, scenario_seed(seed, index),
                   [f"{k}={toml_value(v)}" for k, v in d.sets.items()], d.factors)


@functools.cache
def drawer(kind: str) -> Drawer:
    """The drawer of a kind of campaign (``follow``, ``lines``, ``hold``)."""
    from zarco_tools.campaign.follow_draw import FollowDrawer
    from zarco_tools.campaign.lines_draw import HoldDrawer, LinesDrawer

    drawers: dict[str, Drawer] = {"follow": FollowDrawer(), "lines": LinesDrawer(),
                                  "hold": HoldDrawer()}
    return drawers[kind]
