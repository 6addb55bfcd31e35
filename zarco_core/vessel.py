"""The vessel as the runtime knows it (``[vessel]``, ``[thrusters]``): the hull
model (paper section III) and each thruster's calibrated map f (command → thrust).

Shared by the layers that model the boat: control designs its gains and
allocates through f⁻¹ on it, navigation predicts with it.
"""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec

# Bollard-pull calibration of one Zarco thruster (command → thrust, N), sampled
# from the reference curve (deadband ±5, 125 N forward, 75 N reverse, convex:
# g = 0.3 s + 0.7 s² of the command s beyond the deadband).  On the boat, replace
# with the thruster's measured table.
DEFAULT_TABLE_U = [
    -100.0, -90.0, -80.0, -70.0, -60.0, -50.0, -40.0, -30.0, -20.0, -15.0, -10.0, -5.0,
    5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0,
]
DEFAULT_TABLE_F = [
    -75.0, -62.161, -50.485, -39.972, -30.623, -22.438, -15.416, -9.557, -4.861, -2.95,
    -1.33, 0.0, 0.0, 2.216, 4.917, 8.102, 15.928, 25.693, 37.396, 51.039, 66.62, 84.141,
    103.601, 125.0,
]


@dataclass(slots=True)
class VesselModel:
    """The runtime's nominal model of the vessel (the Zarco's reference values), for feedforward
    and gain design.  Damping coefficients are negative (they oppose motion)."""

    m_kg: float = spec(45.0, "kg", "mass", min=1.0, max=1000.0)
    iz_kgm2: float = spec(9.0, "kg m²", "yaw inertia", min=0.01, max=1000.0)
    x_udot: float = spec(-4.5, "kg", "surge added mass", max=0.0)
    y_vdot: float = spec(-67.5, "kg", "sway added mass", max=0.0)
    n_rdot: float = spec(-15.3, "kg m²", "yaw added inertia", max=0.0)
    x_u: float = spec(-25.0, "N s/m", "linear surge damping", max=0.0)
    x_uu: float = spec(-82.0, "N s²/m²", "quadratic surge damping", max=0.0)
    y_v: float = spec(-112.5, "N s/m", "linear sway damping", max=0.0)
    n_r: float = spec(-24.3, "N m s", "linear yaw damping", max=0.0)
    b_m: float = spec(0.38, "m", "thruster half-spacing", min=0.01, max=5.0)
    l_m: float = spec(0.65, "m", "thruster distance aft of CM", min=0.0, max=5.0)
    thruster_lag_s: float = spec(0.15, "s", "thruster first-order time constant",
                                 min=0.001, max=5.0)


@dataclass(slots=True)
class ThrusterTable:
    """Calibrated map f: command U (-100..100) → thrust F (N), monotone, with deadband."""

    u: list[float] = spec(lambda: list(DEFAULT_TABLE_U), "%", "command points, increasing")
    f_n: list[float] = spec(lambda: list(DEFAULT_TABLE_F), "N", "thrust at each command point")

    def validate(self) -> None:
        if len(self.u) != len(self.f_n):
            raise ValueError(f"f_n: has {len(self.f_n)} points but u has {len(self.u)}")
        if len(self.u) < 2:
            raise ValueError("u: needs at least 2 points")
        for i in range(1, len(self.u)):
            if not self.u[i] > self.u[i - 1]:
                raise ValueError(f"u: not strictly increasing at index {i} ({self.u[i]})")
            if self.f_n[i] < self.f_n[i - 1]:
                raise ValueError(
                    f"f_n: not monotone at index {i} ({self.f_n[i - 1]} → {self.f_n[i]})"
                )
        if self.u[0] < -100 or self.u[-1] > 100:
            raise ValueError("u: points must lie within -100..100")
        if not (self.f_n[0] <= 0.0 <= self.f_n[-1]):
            raise ValueError("f_n: must span zero thrust")


@dataclass(slots=True)
class Thrusters:
    port: ThrusterTable = spec(ThrusterTable)
    starboard: ThrusterTable = spec(ThrusterTable)
