"""The MAVLink parameters: the runtime's gains and failsafe settings, by name.

Each parameter is one field of the running configuration (the same objects the
control loop, the guidance and the supervisor read), so a value set from a
ground station takes effect in the running process: the speed and heading
gains at the next control tick, the LQR weights and the hold/follow settings at
the next mode change (the controller is designed when a mode starts), the
failsafe table at its next evaluation.  Values last until the process ends;
the configuration file is not written.

A value is accepted only within the field's validated range (its ``min`` /
``max``, or one of its ``choices``) and when its section stays valid as a whole
(``position_lost`` cannot be ``hold``, say); anything else is refused with a
reason.  Numbers are REAL32; a field with choices is an INT32 holding the index
of its choice (the list is in the parameter's table).  Values travel as C casts
of the number into the float (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST).
"""

from __future__ import annotations

import dataclasses
import math
import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

REAL32 = 9   # MAV_PARAM_TYPE_REAL32
INT32 = 6    # MAV_PARAM_TYPE_INT32

#: (parameter id, configuration section, field), in the order they are listed
TABLE: tuple[tuple[str, str, str], ...] = (
    ("CTL_LQR_D_M", "control", "lqr_d_m"),
    ("CTL_LQR_INT_MS", "control", "lqr_int_ms"),
    ("CTL_LQR_PSI_DEG", "control", "lqr_psi_deg"),
    ("CTL_LQR_R_DPS", "control", "lqr_r_dps"),
    ("CTL_LQR_V_MPS", "control", "lqr_v_mps"),
    ("CTL_LQR_N_NM", "control", "lqr_n_nm"),
    ("CTL_XTRK_TAU_S", "control", "xtrack_tau_s"),
    ("CTL_INT_WIN_M", "control", "integral_window_m"),
    ("CTL_MAX_ICPT_DEG", "control", "max_intercept_deg"),
    ("CTL_SPD_KP", "control", "speed_kp"),
    ("CTL_SPD_KI", "control", "speed_ki"),
    ("CTL_HDG_KP", "control", "heading_kp"),
    ("CTL_HDG_KD", "control", "heading_kd"),
    ("GDN_SWITCHING", "guidance", "switching"),
    ("GDN_TURN_DPS", "guidance", "turn_rate_dps"),
    ("HOLD_RADIUS_M", "hold", "station_radius_m"),
    ("HOLD_TRANS_MPS", "hold", "transit_speed_mps"),
    ("HOLD_APPR_GAIN", "hold", "approach_gain"),
    ("HOLD_CUR_MIN_MPS", "hold", "current_min_mps"),
    ("HOLD_REALIGN_DEG", "hold", "realign_deg"),
    ("HOLD_K_S", "hold", "k_s"),
    ("HOLD_K_I", "hold", "k_i"),
    ("HOLD_ALONG_M", "hold", "along_clamp_m"),
    ("FOL_K_S", "follow", "k_s"),
    ("FOL_K_I", "follow", "k_i"),
    ("FOL_ALONG_M", "follow", "along_clamp_m"),
    ("FOL_MAX_MPS", "follow", "max_speed_mps"),
    ("FS_POS_LOST", "failsafe", "position_lost"),
    ("FS_POS_LOST_S", "failsafe", "position_lost_s"),
    ("FS_HDG_LOST", "failsafe", "heading_lost"),
    ("FS_HDG_LOST_S", "failsafe", "heading_lost_s"),
    ("FS_THR_SILENT", "failsafe", "thruster_silent"),
    ("FS_THR_SILENT_S", "failsafe", "thruster_silent_s"),
    ("FS_LINK_LOST", "failsafe", "link_lost"),
    ("FS_LINK_LOST_S", "failsafe", "link_lost_s"),
    ("FS_LINK", "failsafe", "link"),
    ("FS_GEOFENCE", "failsafe", "geofence"),
    ("FS_GEOFENCE_S", "failsafe", "geofence_s"),
    ("FS_AUV_LOST", "failsafe", "auv_lost"),
    ("FS_AUV_LOST_S", "failsafe", "auv_lost_s"),
    ("FS_COMP_FAIL", "failsafe", "component_failed"),
    ("FS_COMP_FAIL_S", "failsafe", "component_failed_s"),
    ("FS_CLEAR_S", "failsafe", "clear_after_s"),
    ("FS_AFTER_CLEAR", "failsafe", "after_clear"),
    ("SUP_LEASE_S", "supervisor", "manual_lease_s"),
    ("SUP_MAX_SPD_MPS", "supervisor", "max_speed_mps"),
)


def f32(x: float) -> float:
    """``x`` rounded to a float32, as it travels in PARAM_VALUE / PARAM_SET."""
    return float(struct.unpack("<f", struct.pack("<f", x))[0])


@dataclass(frozen=True, slots=True)
class Param:
    """One parameter: its id, where it lives, and its metadata."""

    name: str
    section: str
    field: str
    index: int
    ptype: int
    unit: str
    doc: str
    lo: float | None
    hi: float | None
    choices: tuple[str, ...]


class ParamTable:
    """The parameters of a running configuration: read and set by id or index."""

    def __init__(self, cfg: RuntimeConfig) -> None:
        self.cfg = cfg
        self.params: list[Param] = []
        self.by_name: dict[str, Param] = {}
        for i, (name, section, fname) in enumerate(TABLE):
            obj = getattr(cfg, section)
            f = {x.name: x for x in dataclasses.fields(obj)}[fname]
            md = f.metadata
            choices = tuple(md.get("choices", ()))
            p = Param(name, section, fname, i, INT32 if choices else REAL32,
                      str(md.get("unit", "")), str(md.get("doc", "")),
                      md.get("min"), md.get("max"), choices)
            self.params.append(p)
            self.by_name[name] = p

    def __len__(self) -> int:
        return len(self.params)

    def find(self, name: str, index: int) -> Param | None:
        """By id (when ``index`` is −1, as PARAM_REQUEST_READ says), else by index."""
        if index >= 0:
            return self.params[index] if index < len(self.params) else None
        return self.by_name.get(name)

    def value(self, p: Param) -> float:
        """The parameter's current value as it travels (a choice's index)."""
        v = getattr(getattr(self.cfg, p.section), p.field)
        if p.choices:
            return float(p.choices.index(v))
        return f32(float(v))

    def set(self, p: Param, value: float) -> tuple[str, Any, Any]:
        """Set ``p`` to ``value`` (as received): ``("", old, new)``, or the reason
        it is refused and the value unchanged."""
        section = getattr(self.cfg, p.section)
        old = getattr(section, p.field)
        if not math.isfinite(value):
            return f"{p.name}: not a number ({value})", old, old
        new: Any
        if p.choices:
            k = round(value)
            if abs(value - k) > 1e-6 or not 0 <= k < len(p.choices):
                opts = ", ".join(f"{i} = {c}" for i, c in enumerate(p.choices))
                return f"{p.name}: must be one of {opts}; got {value:g}", old, old
            new = p.choices[k]
        else:
            new = float(value)
            # a bound sent back as float32 is the bound
            if p.lo is not None and new < p.lo and new == f32(p.lo):
                new = float(p.lo)
            if p.hi is not None and new > p.hi and new == f32(p.hi):
                new = float(p.hi)
            unit = f" {p.unit}" if p.unit else ""
            if p.lo is not None and new < p.lo:
                return f"{p.name}: must be ≥ {p.lo:g}{unit}, got {new:g}", old, old
            if p.hi is not None and new > p.hi:
                return f"{p.name}: must be ≤ {p.hi:g}{unit}, got {new:g}", old, old
        trial = dataclasses.replace(section, **{p.field: new})
        validate = getattr(trial, "validate", None)
        if callable(validate):
            try:
                validate()
            except ValueError as exc:
                return f"{p.name}: {exc}", old, old
        setattr(section, p.field, new)
        return "", old, new

    def describe(self, p: Param) -> str:
        """One line of the parameter table (docs/protocols.md, MAVLink)."""
        rng = (" | ".join(f"{i} {c}" for i, c in enumerate(p.choices)) if p.choices
               else f"{p.lo:g} … {p.hi:g} {p.unit}".rstrip())
        return f"| `{p.name}` | `{p.section}.{p.field}` | {rng} | {p.doc} |"
