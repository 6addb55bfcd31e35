"""The parameters an operator may change while the runtime runs, and how.

A parameter is one key of the running configuration, named by its dotted
path (``failsafe.link_lost_s``: ``[failsafe] link_lost_s`` in the vessel
file).  Its type, unit and range are the configuration's own (the field's
``min``/``max`` or ``choices``); the section must stay valid as a whole
(``failsafe.position_lost`` cannot be ``hold``).  Every change goes through
the supervisor as a ``param`` command (shore ``cmd/param``, MAVLink
PARAM_SET, ``zarco ctl param``): it is validated here, refused while the boat
is under way for the sections where a change is unsafe then (the failsafe
table, the geofence: :data:`LOCKED_UNDER_WAY`), applied to the live
configuration the components read, acknowledged, published as a
:class:`~zarco_core.messages.ParamChange`, recorded, and applied again by
``zarco log replay``.  Values last until the process ends; the file is not
written.

When a change takes effect: the speed and heading gains at the next control
tick; the LQR weights, the hold and follow settings at the next mode change
(the new design is solved off the tick); the failsafe table, the geofence,
the manual lease, the speed limit and the command rate at once.

:func:`param_table` lists them all (name, type, range, current value): what a
MAVLink ground station's PARAM_REQUEST_LIST is answered from.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from zarco_core.messages import ParamValue

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

#: the parameters, by dotted name, in the order they are listed
NAMES: tuple[str, ...] = (
    "control.lqr_d_m", "control.lqr_int_ms", "control.lqr_psi_deg", "control.lqr_r_dps",
    "control.lqr_v_mps", "control.lqr_n_nm", "control.xtrack_tau_s",
    "control.integral_window_m", "control.max_intercept_deg", "control.current_feedforward",
    "control.gust_feedforward", "control.mismatch_compensation", "control.speed_kp",
    "control.speed_ki", "control.heading_kp", "control.heading_kd",
    "guidance.switching", "guidance.turn_rate_dps",
    "hold.station_radius_m", "hold.transit_speed_mps", "hold.approach_gain",
    "hold.current_min_mps", "hold.realign_deg", "hold.k_s", "hold.k_i", "hold.along_clamp_m",
    "follow.k_s", "follow.k_i", "follow.along_clamp_m", "follow.max_speed_mps",
    "failsafe.position_lost", "failsafe.position_lost_s", "failsafe.heading_lost",
    "failsafe.heading_lost_s", "failsafe.thruster_silent", "failsafe.thruster_silent_s",
    "failsafe.link_lost", "failsafe.link_lost_s", "failsafe.link", "failsafe.geofence",
    "failsafe.geofence_s", "failsafe.auv_lost", "failsafe.auv_lost_s",
    "failsafe.component_failed", "failsafe.component_failed_s", "failsafe.clear_after_s",
    "failsafe.after_clear",
    "geofence.radius_m", "geofence.polygon",
    "supervisor.manual_lease_s", "supervisor.max_speed_mps", "supervisor.command_rate_hz",
    "supervisor.command_burst",
)
#: sections whose parameters are refused while the boat is under way
LOCKED_UNDER_WAY = frozenset({"failsafe", "geofence"})


class ParamRefused(ValueError):
    """A parameter change that is not accepted; the message names the parameter."""


@dataclass(frozen=True, slots=True)
class ParamInfo:
    """One parameter: its dotted ``name``, ``kind`` (``float``, ``int``, ``bool``,
    ``choice``: one of ``choices``, ``points``: a list of [lat_deg, lon_deg]),
    ``unit``, ``doc``, range ``lo``..``hi`` (numbers; None: unbounded), current
    ``value``, and whether it is refused while under way (``locked_under_way``)."""

    name: str
    kind: str
    unit: str
    doc: str
    lo: float | None
    hi: float | None
    choices: tuple[str, ...]
    value: ParamValue
    locked_under_way: bool


def _field(cfg: RuntimeConfig, name: str) -> tuple[Any, dataclasses.Field[Any]]:
    section, _, key = name.partition(".")
    if name not in NAMES:
        raise ParamRefused(f"{name}: no such parameter (`zarco ctl params` lists them)")
    obj = getattr(cfg, section)
    f = next(x for x in dataclasses.fields(obj) if x.name == key)
    return obj, f


def _kind(f: dataclasses.Field[Any]) -> str:
    """The parameter's kind from its field's declared type."""
    if f.metadata.get("choices"):
        return "choice"
    t = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))
    kinds = {"bool": "bool", "int": "int", "float": "float", "list[list[float]]": "points"}
    return kinds[t]


def _plain(v: Any) -> ParamValue:
    if isinstance(v, list):
        return [[float(a), float(b)] for a, b in v]
    out: ParamValue = v
    return out


def describe(cfg: RuntimeConfig, name: str) -> ParamInfo:
    """The parameter ``name`` of ``cfg`` (raises :class:`ParamRefused` if there is none)."""
    obj, f = _field(cfg, name)
    value = getattr(obj, f.name)
    md = f.metadata
    lo, hi = md.get("min"), md.get("max")
    return ParamInfo(name, _kind(f), str(md.get("unit", "")), str(md.get("doc", "")),
                     None if lo is None else float(lo), None if hi is None else float(hi),
                     tuple(md.get("choices", ())), _plain(value),
                     name.partition(".")[0] in LOCKED_UNDER_WAY)


def param_table(cfg: RuntimeConfig) -> list[ParamInfo]:
    """Every parameter with its type, range and current value, in a fixed order."""
    return [describe(cfg, n) for n in NAMES]


def coerce(info: ParamInfo, value: Any) -> ParamValue:
    """``value`` as the parameter's type, within its range, or :class:`ParamRefused`."""
    name, kind = info.name, info.kind
    unit = f" {info.unit}" if info.unit and kind in ("float", "int") else ""
    if kind == "bool":
        if not isinstance(value, bool):
            raise ParamRefused(f"{name}: must be true or false")
        return value
    if kind == "choice":
        if not isinstance(value, str) or value not in info.choices:
            raise ParamRefused(f"{name}: must be one of {', '.join(info.choices)}")
        return value
    if kind == "points":
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(p, (list, tuple)) and len(p) == 2 for p in value):
            raise ParamRefused(f"{name}: must be a list of [lat_deg, lon_deg]")
        return [[float(p[0]), float(p[1])] for p in value]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParamRefused(f"{name}: must be a number")
    x = float(value)
    if not math.isfinite(x):
        raise ParamRefused(f"{name}: must be a finite number")
    if info.lo is not None and x < info.lo:
        raise ParamRefused(f"{name}: must be ≥ {info.lo:g}{unit}, got {x:g}")
    if info.hi is not None and x > info.hi:
        raise ParamRefused(f"{name}: must be ≤ {info.hi:g}{unit}, got {x:g}")
    if kind == "int":
        if x != math.floor(x):
            raise ParamRefused(f"{name}: must be a whole number, got {x:g}")
        return int(x)
    return x


def apply(cfg: RuntimeConfig, name: str, value: Any, under_way: str = "") -> tuple[
        ParamValue, ParamValue]:
    """Set parameter ``name`` of the live ``cfg`` to ``value``: (old, new).

    ``under_way``: the mode the boat is under way in ("" when it is not); a
    parameter of :data:`LOCKED_UNDER_WAY` is then refused.  Raises
    :class:`ParamRefused` (nothing changed) with the parameter and the reason.
    """
    info = describe(cfg, name)
    if under_way and info.locked_under_way:
        raise ParamRefused(f"{name}: the {name.partition('.')[0]} settings do not change "
                           f"under way (mode {under_way}); stop or disarm first")
    new = coerce(info, value)
    obj, f = _field(cfg, name)
    trial = dataclasses.replace(obj, **{f.name: new})
    validate = getattr(trial, "validate", None)
    if callable(validate):
        try:
            validate()
        except ValueError as exc:
            raise ParamRefused(f"{name}: {exc}") from None
    old = info.value
    setattr(obj, f.name, new)
    return old, _plain(new)
