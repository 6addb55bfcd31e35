"""A campaign's spec file (``config/campaigns/*.toml``): what is drawn, from
which ranges, in which families, and the targets each mission is judged by.

::

    [campaign]
    name = "follow"
    kind = "follow"                          # the drawer: follow, lines or hold
    scenario = "../scenarios/follow_turn.toml"   # the base scenario, from this file
    missions = 60                            # the default --n

    [targets]                                # names of the drawer's targets
    distance_median_m = 1.0

    [ranges]                                 # [low, high] of every drawn number
    auv_speed_mps = [0.5, 1.4]

    [choices.calibration]                    # weights of a drawn category
    exact = 2
    sound_speed = 1

    [families.lawnmower]                     # a family: its weight, its own
    weight = 3                               # settings, ranges and choices
    route = "lawnmower"
    ranges = { leg_m = [60.0, 130.0] }

A family's ranges and choices replace the campaign's of the same name.  Names
are checked against the drawer's (:func:`zarco_tools.campaign.draw.drawer`):
an unknown or missing name, a range whose low end is above its high end or
outside the drawer's bounds, a weight that is not positive, is refused with
the file, the key and the reason.

The spec travels to the workers as data (:class:`CampaignSpec` holds the base
scenario's TOML already read), so a worker needs only the package.
"""

from __future__ import annotations

import copy
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zarco_core.config import ConfigError, load_toml

#: the drawers a spec may name
KINDS = ("follow", "lines", "hold")


@dataclass(slots=True)
class Family:
    """A family of missions: its ``weight`` among the families, its settings
    (``route = "lawnmower"``), and the ranges and choices it draws from
    instead of the campaign's."""

    name: str
    weight: float
    settings: dict[str, Any] = field(default_factory=dict)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    choices: dict[str, dict[str, float]] = field(default_factory=dict)


@dataclass(slots=True)
class CampaignSpec:
    """A campaign, read from its file: everything a worker needs to draw and run
    any mission of it."""

    file: str
    name: str
    kind: str
    scenario_file: str
    scenario: dict[str, Any]
    missions: int
    targets: dict[str, float]
    ranges: dict[str, tuple[float, float]]
    choices: dict[str, dict[str, float]]
    families: list[Family]
    digest: str

    def family(self, name: str) -> Family:
        return next(f for f in self.families if f.name == name)

    def range(self, fam: Family, name: str) -> tuple[float, float]:
        """The range ``name`` as ``fam`` draws it."""
        return fam.ranges.get(name) or self.ranges[name]

    def has_range(self, fam: Family, name: str) -> bool:
        return name in fam.ranges or name in self.ranges

    def choice(self, fam: Family, name: str) -> dict[str, float]:
        """The weights of the category ``name`` as ``fam`` draws it."""
        return fam.choices.get(name) or self.choices[name]

    def scenario_data(self) -> dict[str, Any]:
        """A fresh copy of the base scenario's TOML (overrides change it in place)."""
        return copy.deepcopy(self.scenario)


def _range(file: str, key: str, v: Any, bounds: tuple[float, float] | None
           ) -> tuple[float, float]:
    if (not isinstance(v, list) or len(v) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
        raise ConfigError(file, key, f"must be [low, high], got {v!r}")
    lo, hi = float(v[0]), float(v[1])
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ConfigError(file, key, f"must be [low, high] with low ≤ high, got {v!r}")
    if bounds is not None and (lo < bounds[0] or hi > bounds[1]):
        raise ConfigError(file, key, f"must lie within [{bounds[0]:g}, {bounds[1]:g}], "
                          f"got {v!r}")
    return lo, hi


def _choices(file: str, key: str, v: Any, allowed: tuple[str, ...]) -> dict[str, float]:
    if not isinstance(v, dict) or not v:
        raise ConfigError(file, key, "must be a table of weights, e.g. { a = 1, b = 2 }")
    out = {}
    for name, w in v.items():
        if name not in allowed:
            raise ConfigError(file, f"{key}.{name}", f"unknown; one of {', '.join(allowed)}")
        if not isinstance(w, (int, float)) or isinstance(w, bool) or not w >= 0.0:
            raise ConfigError(file, f"{key}.{name}", f"weight must be a number ≥ 0, got {w!r}")
        out[name] = float(w)
    if sum(out.values()) <= 0.0:
        raise ConfigError(file, key, "the weights add up to 0")
    return out


def load_spec(path: str | Path) -> CampaignSpec:
    """Read and check a campaign spec; raises ConfigError naming file and key."""
    from zarco_tools.campaign.draw import drawer as drawer_of

    file = str(path)
    raw = Path(path).read_bytes() if Path(path).is_file() else b""
    data = load_toml(path)
    unknown = set(data) - {"campaign", "targets", "ranges", "choices", "families"}
    if unknown:
        raise ConfigError(file, sorted(unknown)[0], "unknown table; campaign, targets, "
                          "ranges, choices, families")
    head = data.get("campaign", {})
    for k in head:
        if k not in ("name", "kind", "scenario", "missions"):
            raise ConfigError(file, f"campaign.{k}", "unknown key; name, kind, scenario, "
                              "missions")
    kind = head.get("kind")
    if kind not in KINDS:
        raise ConfigError(file, "campaign.kind", f"must be one of {', '.join(KINDS)}, "
                          f"got {kind!r}")
    drawer = drawer_of(kind)
    name = head.get("name", Path(path).stem)
    if not isinstance(name, str) or not name:
        raise ConfigError(file, "campaign.name", "must be a non-empty string")
    missions = head.get("missions", 60)
    if not isinstance(missions, int) or isinstance(missions, bool) or missions < 1:
        raise ConfigError(file, "campaign.missions", f"must be an integer ≥ 1, got {missions!r}")
    scn = head.get("scenario")
    if not isinstance(scn, str) or not scn:
        raise ConfigError(file, "campaign.scenario", "must name the base scenario file")
    scn_path = (Path(path).parent / scn)
    scenario = load_toml(scn_path)

    targets: dict[str, float] = {}
    for k, v in data.get("targets", {}).items():
        if k not in drawer.targets:
            raise ConfigError(file, f"targets.{k}", f"unknown target; one of "
                              f"{', '.join(drawer.targets)}")
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not v > 0.0:
            raise ConfigError(file, f"targets.{k}", f"must be a number > 0, got {v!r}")
        targets[k] = float(v)
    missing = [k for k in drawer.targets if k not in targets]
    if missing:
        raise ConfigError(file, f"targets.{missing[0]}", "missing")

    def ranges(table: Any, where: str) -> dict[str, tuple[float, float]]:
        if not isinstance(table, dict):
            raise ConfigError(file, where, "must be a table")
        out = {}
        for k, v in table.items():
            if k not in drawer.ranges:
                raise ConfigError(file, f"{where}.{k}", f"unknown range; one of "
                                  f"{', '.join(sorted(drawer.ranges))}")
            out[k] = _range(file, f"{where}.{k}", v, drawer.ranges[k])
        return out

    def choices(table: Any, where: str) -> dict[str, dict[str, float]]:
        if not isinstance(table, dict):
            raise ConfigError(file, where, "must be a table")
        out = {}
        for k, v in table.items():
            if k not in drawer.choices:
                raise ConfigError(file, f"{where}.{k}", f"unknown choice; one of "
                                  f"{', '.join(sorted(drawer.choices))}")
            out[k] = _choices(file, f"{where}.{k}", v, drawer.choices[k])
        return out

    shared_ranges = ranges(data.get("ranges", {}), "ranges")
    shared_choices = choices(data.get("choices", {}), "choices")
    fams_raw = data.get("families", {})
    if not isinstance(fams_raw, dict) or not fams_raw:
        raise ConfigError(file, "families", "at least one family")
    families = []
    for fname, f in fams_raw.items():
        where = f"families.{fname}"
        if not isinstance(f, dict):
            raise ConfigError(file, where, "must be a table")
        w = f.get("weight", 1.0)
        if not isinstance(w, (int, float)) or isinstance(w, bool) or not w > 0.0:
            raise ConfigError(file, f"{where}.weight", f"must be a number > 0, got {w!r}")
        settings = {k: v for k, v in f.items() if k not in ("weight", "ranges", "choices")}
        for k, v in settings.items():
            allowed = drawer.settings.get(k)
            if allowed is None:
                raise ConfigError(file, f"{where}.{k}", f"unknown setting; one of "
                                  f"{', '.join(sorted(drawer.settings)) or 'none'}")
            if v not in allowed:
                raise ConfigError(file, f"{where}.{k}", f"must be one of "
                                  f"{', '.join(map(str, allowed))}, got {v!r}")
        families.append(Family(fname, float(w), settings,
                               ranges(f.get("ranges", {}), f"{where}.ranges"),
                               choices(f.get("choices", {}), f"{where}.choices")))
    spec = CampaignSpec(file, name, kind, str(scn_path), scenario, missions, targets,
                        shared_ranges, shared_choices, families,
                        hashlib.sha256(raw + b"\0" + scn_path.read_bytes()).hexdigest()[:16])
    for fam in families:
        for k in drawer.required_ranges(spec, fam):
            if not spec.has_range(fam, k):
                raise ConfigError(file, f"ranges.{k}", f"missing (family {fam.name} draws it)")
        for k in drawer.required_choices(spec, fam):
            if k not in fam.choices and k not in spec.choices:
                raise ConfigError(file, f"choices.{k}", f"missing (family {fam.name} draws it)")
    drawer.check(spec)
    return spec


def parse_choice(text: str, kind: str) -> tuple[str, dict[str, float]]:
    """``NAME=VALUE[:WEIGHT][,VALUE[:WEIGHT]...]`` (``--choice``): the weights a
    category is drawn with instead of the spec's (a value without a weight
    weighs 1); refused with the reason when the name, a value or a weight is
    not the drawer's."""
    from zarco_tools.campaign.draw import drawer as drawer_of

    where = "--choice"
    name, eq, rest = text.partition("=")
    name = name.strip()
    allowed = drawer_of(kind).choices
    if not eq or name not in allowed:
        raise ConfigError(where, text, f"must be NAME=VALUE[:WEIGHT][,...] with NAME one of "
                          f"{', '.join(sorted(allowed))}")
    table: dict[str, Any] = {}
    for item in rest.split(","):
        value, colon, w = item.strip().partition(":")
        try:
            table[value] = float(w) if colon else 1.0
        except ValueError:
            raise ConfigError(where, text, f"weight of {value!r} is not a number: {w!r}"
                              ) from None
    return name, _choices(where, name, table, allowed[name])


def with_choices(spec: CampaignSpec, choices: dict[str, dict[str, float]]) -> CampaignSpec:
    """``spec`` drawing the categories ``choices`` with these weights in every
    family.  A category is picked with one random number whatever its weights,
    so every other draw of a mission stays the same: the same missions with,
    say, and without the AUV's plan (except an adaptive mission's route, which
    draws where the AUV leaves its plan)."""
    from zarco_tools.campaign.draw import drawer as drawer_of

    if not choices:
        return spec
    out = copy.deepcopy(spec)
    out.choices.update(copy.deepcopy(choices))
    for fam in out.families:
        for name in choices:
            fam.choices.pop(name, None)
    drawer_of(out.kind).check(out)
    return out
