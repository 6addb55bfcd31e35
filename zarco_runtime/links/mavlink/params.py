"""The MAVLink parameters: ids of at most 16 characters for the supervisor's
parameters (:mod:`zarco_runtime.supervision.params`, dotted configuration
keys such as ``failsafe.link_lost_s``).

The registry is the supervisor's: which keys may change, their types, ranges
and current values, which are refused while under way.  This module only
names them for a ground station and translates values: a number travels as a
REAL32; an integer, a flag (0 / 1) and a choice (the index of the choice, the
list in the parameter's table) as an INT32, every value as a C cast of the
number into the float (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST).  A key
that is a list of points (the geofence polygon) has no MAVLink id.

A PARAM_SET becomes the supervisor's ``param`` command; nothing here writes
the configuration.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING

from zarco_core.messages import ParamValue
from zarco_runtime.supervision.params import ParamInfo, describe

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig

REAL32 = 9   # MAV_PARAM_TYPE_REAL32
INT32 = 6    # MAV_PARAM_TYPE_INT32
#: longest MAVLink parameter id
ID_LEN = 16

#: (parameter id, the supervisor's parameter), in the order they are listed
TABLE: tuple[tuple[str, str], ...] = (
    ("CTL_LQR_D_M", "control.lqr_d_m"),
    ("CTL_LQR_INT_MS", "control.lqr_int_ms"),
    ("CTL_LQR_PSI_DEG", "control.lqr_psi_deg"),
    ("CTL_LQR_R_DPS", "control.lqr_r_dps"),
    ("CTL_LQR_V_MPS", "control.lqr_v_mps"),
    ("CTL_LQR_N_NM", "control.lqr_n_nm"),
    ("CTL_XTRK_TAU_S", "control.xtrack_tau_s"),
    ("CTL_INT_WIN_M", "control.integral_window_m"),
    ("CTL_MAX_ICPT_DEG", "control.max_intercept_deg"),
    ("CTL_CUR_FF", "control.current_feedforward"),
    ("CTL_GUST_FF", "control.gust_feedforward"),
    ("CTL_MISMATCH", "control.mismatch_compensation"),
    ("CTL_SPD_KP", "control.speed_kp"),
    ("CTL_SPD_KI", "control.speed_ki"),
    ("CTL_HDG_KP", "control.heading_kp"),
    ("CTL_HDG_KD", "control.heading_kd"),
    ("GDN_SWITCHING", "guidance.switching"),
    ("GDN_TURN_DPS", "guidance.turn_rate_dps"),
    ("HOLD_RADIUS_M", "hold.station_radius_m"),
    ("HOLD_TRANS_MPS", "hold.transit_speed_mps"),
    ("HOLD_APPR_GAIN", "hold.approach_gain"),
    ("HOLD_CUR_MIN_MPS", "hold.current_min_mps"),
    ("HOLD_REALIGN_DEG", "hold.realign_deg"),
    ("HOLD_K_S", "hold.k_s"),
    ("HOLD_K_I", "hold.k_i"),
    ("HOLD_ALONG_M", "hold.along_clamp_m"),
    ("FOL_K_S", "follow.k_s"),
    ("FOL_K_I", "follow.k_i"),
    ("FOL_ALONG_M", "follow.along_clamp_m"),
    ("FOL_MAX_MPS", "follow.max_speed_mps"),
    ("FS_POS_LOST", "failsafe.position_lost"),
    ("FS_POS_LOST_S", "failsafe.position_lost_s"),
    ("FS_HDG_LOST", "failsafe.heading_lost"),
    ("FS_HDG_LOST_S", "failsafe.heading_lost_s"),
    ("FS_THR_SILENT", "failsafe.thruster_silent"),
    ("FS_THR_SILENT_S", "failsafe.thruster_silent_s"),
    ("FS_LINK_LOST", "failsafe.link_lost"),
    ("FS_LINK_LOST_S", "failsafe.link_lost_s"),
    ("FS_LINK", "failsafe.link"),
    ("FS_GEOFENCE", "failsafe.geofence"),
    ("FS_GEOFENCE_S", "failsafe.geofence_s"),
    ("FS_AUV_LOST", "failsafe.auv_lost"),
    ("FS_AUV_LOST_S", "failsafe.auv_lost_s"),
    ("FS_COMP_FAIL", "failsafe.component_failed"),
    ("FS_COMP_FAIL_S", "failsafe.component_failed_s"),
    ("FS_CLEAR_S", "failsafe.clear_after_s"),
    ("FS_AFTER_CLEAR", "failsafe.after_clear"),
    ("FENCE_RADIUS_M", "geofence.radius_m"),
    ("SUP_LEASE_S", "supervisor.manual_lease_s"),
    ("SUP_MAX_SPD_MPS", "supervisor.max_speed_mps"),
    ("SUP_CMD_RATE_HZ", "supervisor.command_rate_hz"),
    ("SUP_CMD_BURST", "supervisor.command_burst"),
)


def shortest(x: float) -> float:
    """The number with the fewest significant digits that is the same float32 as
    ``x`` (a ground station's 0.1 arrives as 0.10000000149011612: the
    configuration gets 0.1)."""
    x32 = f32(x)
    for digits in range(1, 10):
        y = float(f"{x:.{digits}g}")
        if f32(y) == x32:
            return y
    return float(x)


def f32(x: float) -> float:
    """``x`` rounded to a float32, as it travels in PARAM_VALUE / PARAM_SET."""
    return float(struct.unpack("<f", struct.pack("<f", x))[0])


@dataclass(frozen=True, slots=True)
class Param:
    """One MAVLink parameter: its ``name`` (id), the supervisor's ``key``, its
    ``index`` in the list and its ``ptype`` (REAL32 or INT32)."""

    name: str
    key: str
    index: int
    ptype: int


class ParamTable:
    """The MAVLink parameters of a running configuration: looked up by id or
    index; values read from the supervisor's registry and translated both ways."""

    def __init__(self, cfg: RuntimeConfig) -> None:
        self.cfg = cfg
        self.params: list[Param] = []
        self.by_name: dict[str, Param] = {}
        self.by_key: dict[str, Param] = {}
        for i, (name, key) in enumerate(TABLE):
            info = describe(cfg, key)  # a key the registry does not have: an error here
            p = Param(name, key, i, REAL32 if info.kind == "float" else INT32)
            self.params.append(p)
            self.by_name[name] = p
            self.by_key[key] = p

    def __len__(self) -> int:
        return len(self.params)

    def find(self, name: str, index: int) -> Param | None:
        """By id (when ``index`` is −1, as PARAM_REQUEST_READ says), else by index."""
        if index >= 0:
            return self.params[index] if index < len(self.params) else None
        return self.by_name.get(name)

    def info(self, p: Param) -> ParamInfo:
        """The parameter as the supervisor's registry has it now."""
        return describe(self.cfg, p.key)

    def wire(self, p: Param, value: ParamValue | None = None) -> float:
        """``value`` (default: the current one) as it travels."""
        info = self.info(p)
        v = info.value if value is None else value
        if info.kind == "choice":
            return float(info.choices.index(str(v)))
        if isinstance(v, (bool, int, float)):
            return f32(float(v))
        raise ValueError(f"{p.name}: {info.kind} has no MAVLink value")

    def from_wire(self, p: Param, x: float) -> ParamValue:
        """A received value as the parameter's type, for the supervisor to judge;
        ValueError saying why it is not one."""
        info = self.info(p)
        if x != x or x in (float("inf"), float("-inf")):
            raise ValueError(f"{p.name}: not a number ({x})")
        if info.kind == "float":
            # a bound sent back as float32 is the bound
            for bound in (info.lo, info.hi):
                if bound is not None and x != bound and x == f32(bound):
                    return float(bound)
            return shortest(x)
        k = round(x)
        if abs(x - k) > 1e-6:
            raise ValueError(f"{p.name}: must be a whole number, got {x:g}")
        if info.kind == "choice":
            if not 0 <= k < len(info.choices):
                opts = ", ".join(f"{i} = {c}" for i, c in enumerate(info.choices))
                raise ValueError(f"{p.name}: must be one of {opts}; got {x:g}")
            return info.choices[k]
        if info.kind == "bool":
            if k not in (0, 1):
                raise ValueError(f"{p.name}: must be 0 or 1, got {x:g}")
            return bool(k)
        return int(k)

    def describe(self, p: Param) -> str:
        """One line of the parameter table (docs/protocols.md, MAVLink): id, key,
        the value now (a default configuration's: the default), range, meaning."""
        info = self.info(p)
        if info.kind == "choice":
            rng = ", ".join(f"{i} {c}" for i, c in enumerate(info.choices))
        elif info.kind == "bool":
            rng = "0 off, 1 on"
        else:
            lo = "" if info.lo is None else f"{info.lo:g}"
            hi = "" if info.hi is None else f"{info.hi:g}"
            rng = f"{lo} … {hi} {info.unit}".rstrip()
        lock = " (not under way)" if info.locked_under_way else ""
        v = info.value
        shown = f"{self.wire(p):g}" + (f" ({v})" if info.kind == "choice" else "")
        return f"| `{p.name}` | `{p.key}`{lock} | {shown} | {rng} | {info.doc} |"
