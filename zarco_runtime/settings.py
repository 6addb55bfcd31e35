"""The runtime's configuration schema (``config/zarco.toml`` and the
``[runtime]`` table of a scenario).

Every field carries its unit and range; :func:`zarco_core.config.build`
validates a TOML table against these dataclasses.  Defaults are the Zarco's
reference hull and thruster model (``[vessel]``, ``[thrusters]``) and the tuned
gains of the line-tracking controller.
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.settings import Device
from zarco_core.config import spec
from zarco_core.geodesy import Origin
from zarco_core.vessel import (
    DEFAULT_TABLE_F,
    DEFAULT_TABLE_U,
    Thrusters,
    ThrusterTable,
    VesselModel,
)
from zarco_runtime.control.settings import XTRACK_RATE_TAU_S, Control, xtrack_rate_tau_s
from zarco_runtime.guidance.follow_settings import FollowSettings
from zarco_runtime.guidance.settings import Guidance, HoldSettings
from zarco_runtime.links.mavlink.settings import MavlinkSettings
from zarco_runtime.links.recorder.settings import Record
from zarco_runtime.links.shore.settings import Shore
from zarco_runtime.navigation.ekf_config import EkfSettings
from zarco_runtime.navigation.settings import Navigation
from zarco_runtime.supervision.settings import Failsafe, Geofence, Supervisor
from zarco_runtime.tracking.params import TrackerParams


@dataclass(slots=True)
class Devices:
    """The vessel's devices.  Every enabled device needs its ``url`` (a serial
    path, ``serial://``, ``tcp://HOST:PORT``); two devices cannot share one."""

    gps: Device = spec(Device, doc="RTK GPS receiver (NMEA 0183; RTCM3 in)")
    compass: Device = spec(Device, doc="compass/IMU (NMEA 0183)")
    thrusters: Device = spec(Device, doc="thruster controller ($PZTHR out, $PZTHS in)")
    buoy: Device = spec(lambda: Device(enabled=False, stale_s=5.0),
                        doc="radio feed of the LBL listening buoy ($PZBAE, $PZBST)")

    def items(self) -> list[tuple[str, Device]]:
        return [("gps", self.gps), ("compass", self.compass), ("thrusters", self.thrusters),
                ("buoy", self.buoy)]


@dataclass(slots=True)
class RuntimeConfig:
    """Everything ``zarco run`` needs."""

    origin: Origin = spec(Origin)
    devices: Devices = spec(Devices)
    vessel: VesselModel = spec(VesselModel)
    thrusters: Thrusters = spec(Thrusters)
    navigation: Navigation = spec(Navigation)
    control: Control = spec(Control)
    guidance: Guidance = spec(Guidance)
    follow: FollowSettings = spec(FollowSettings)
    tracker: TrackerParams = spec(TrackerParams)
    ekf: EkfSettings = spec(EkfSettings)
    hold: HoldSettings = spec(HoldSettings)
    supervisor: Supervisor = spec(Supervisor)
    failsafe: Failsafe = spec(Failsafe)
    geofence: Geofence = spec(Geofence)
    record: Record = spec(Record, doc="the recorder (MCAP of every bus message and raw chunk)")
    mavlink: MavlinkSettings = spec(MavlinkSettings, doc="MAVLink endpoint (QGroundControl, "
                                    "MAVProxy)")
    shore: Shore = spec(Shore, doc="shore supervision over zenoh")


__all__ = [
    "DEFAULT_TABLE_F", "DEFAULT_TABLE_U", "XTRACK_RATE_TAU_S", "Control", "Devices", "Failsafe",
    "Guidance", "Navigation", "Origin", "RuntimeConfig", "ThrusterTable", "Thrusters",
    "VesselModel", "xtrack_rate_tau_s",
]
