"""The boat's telemetry as MAVLink messages, built from the newest values on
the bus: HEARTBEAT, SYS_STATUS, GPS_RAW_INT, GLOBAL_POSITION_INT, ATTITUDE,
VFR_HUD, SERVO_OUTPUT_RAW, HOME_POSITION and AUTOPILOT_VERSION.

A builder returns None when it has nothing to say yet (no estimate, no home).
A number that is not finite (an estimator's NaN) goes out as 0, never as a
message that fails to pack.  Units on the wire are MAVLink's: degrees × 1e7,
millimetres, centimetres per second, centidegrees."""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from importlib import metadata
from typing import Any

from zarco_core.messages import (
    Attitude,
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsVelocity,
    NavState,
    ThrusterCommand,
)
from zarco_runtime.links.mavlink.core import Core
from zarco_runtime.links.mavlink.protocol import (
    CUSTOM_MODE,
    UINT16_MAX,
    base_mode,
    mav,
    thrust_to_pwm,
)

#: GpsFix quality → GPS_RAW_INT fix_type
FIX_TYPE = {
    FixQuality.NONE: mav.GPS_FIX_TYPE_NO_FIX,
    FixQuality.SINGLE: mav.GPS_FIX_TYPE_3D_FIX,
    FixQuality.DGPS: mav.GPS_FIX_TYPE_DGPS,
    FixQuality.RTK_FLOAT: mav.GPS_FIX_TYPE_RTK_FLOAT,
    FixQuality.RTK_FIXED: mav.GPS_FIX_TYPE_RTK_FIXED,
}
#: a GpsFix older than this is reported as no fix, a GGA's quality or a GST's
#: errors older than this as unknown (s)
GPS_STALE_S = 2.0
#: GPS_RAW_INT's "unknown" satellite count
SATS_UNKNOWN = 255

#: a builder: the clock time (s) → a pymavlink message, or None
Builder = Callable[[float], Any]


def r_int(x: float) -> int:
    """``x`` rounded to an integer for a message field; 0 when not a number (a
    message must never fail to build on a NaN from an estimator)."""
    return round(x) if math.isfinite(x) else 0


@functools.cache
def sw_version() -> int:
    """``flight_sw_version``: major, minor, patch, type (dev) in the four bytes."""
    try:
        parts = [int(x) for x in metadata.version("zarco-runtime").split(".")[:3]]
    except (metadata.PackageNotFoundError, ValueError):
        parts = [0, 0, 0]
    parts += [0] * (3 - len(parts))
    return (parts[0] << 24) | (parts[1] << 16) | (parts[2] << 8) | int(
        mav.FIRMWARE_VERSION_TYPE_DEV)


class Telemetry:
    """Builds the boat's messages (see the module docstring)."""

    def __init__(self, core: Core) -> None:
        self.core = core
        bus = core.bus
        self.nav = bus.latest(NavState)
        #: the newest fix (any sentence), and the newest that says how good it is
        #: (GGA, GNS: quality, satellites, HDOP, altitude)
        self.fix: GpsFix | None = None
        self.quality: GpsFix | None = None
        self.gst = bus.latest(GpsErrorStats)
        self.vel = bus.latest(GpsVelocity)
        self.att = bus.latest(Attitude)
        self.thrust = bus.latest(ThrusterCommand)
        self.cpu = (time.process_time(), time.monotonic())
        self.load_permille = 0

    def builders(self) -> dict[str, Builder]:
        """Builder of each message this module builds, by MAVLink name."""
        return {
            "HEARTBEAT": self.heartbeat,
            "SYS_STATUS": self.sys_status,
            "GPS_RAW_INT": self.gps_raw_int,
            "GLOBAL_POSITION_INT": self.global_position_int,
            "ATTITUDE": self.attitude,
            "VFR_HUD": self.vfr_hud,
            "SERVO_OUTPUT_RAW": self.servo_output_raw,
            "HOME_POSITION": self.home_position,
        }

    def on_fix(self, g: GpsFix) -> None:
        """A GpsFix from the receiver.  A receiver sends several sentences per epoch
        (GGA then RMC, say) and only some carry the satellites, the HDOP, the
        altitude and the RTK quality: those are kept apart, so that a later RMC
        does not hide them."""
        self.fix = g
        if g.num_sats is not None or g.hdop is not None:
            self.quality = g

    def measure_load(self) -> None:
        """The runtime's CPU load (‰ of one core) since the last call."""
        p, w = time.process_time(), time.monotonic()
        p0, w0 = self.cpu
        if w > w0:
            self.load_permille = max(0, min(1000, int(1000.0 * (p - p0) / (w - w0))))
        self.cpu = (p, w)

    @staticmethod
    def boot_ms(now: float) -> int:
        return int(now * 1000.0) & 0xFFFFFFFF

    def usec(self, now: float) -> int:
        return int(self.core.clock.utc(now) * 1e6)

    def heartbeat(self, now: float) -> Any:
        """None until the supervisor's first status: a ground station that hears
        the boat can ask for its mode, arming and home and get them."""
        c = self.core
        st = c.status
        if st is None:
            return None
        if st.failsafes:
            state = mav.MAV_STATE_CRITICAL
        elif c.armed:
            state = mav.MAV_STATE_ACTIVE
        else:
            state = mav.MAV_STATE_STANDBY
        return mav.MAVLink_heartbeat_message(
            mav.MAV_TYPE_SURFACE_BOAT, mav.MAV_AUTOPILOT_GENERIC,
            base_mode(c.mode, c.armed), CUSTOM_MODE[c.mode], state, 3)

    def sys_status(self, now: float) -> Any:
        c = self.core
        dev = c.cfg.devices
        st = c.status
        n = self.nav.value

        def ok(name: str) -> bool:
            d = st.devices.get(name) if st is not None else None
            return d is not None and d.state == "ok"

        present = health = 0
        for bit, on, good in (
            (mav.MAV_SYS_STATUS_SENSOR_GPS, dev.gps.enabled, ok("gps")),
            (mav.MAV_SYS_STATUS_SENSOR_3D_MAG, dev.compass.enabled, ok("compass")),
            (mav.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS, dev.thrusters.enabled, ok("thrusters")),
            (mav.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL, True,
             n is not None and n.pos_valid),
            (mav.MAV_SYS_STATUS_SENSOR_YAW_POSITION, True, n is not None and n.heading_valid),
        ):
            if on:
                present |= bit
                if good:
                    health |= bit
        # the geofence as ArduPilot reports it: healthy unless breached (a GCS says
        # "fence breach" when this bit drops)
        fence = c.cfg.geofence
        if fence.radius_m > 0.0 or fence.polygon:
            present |= mav.MAV_SYS_STATUS_GEOFENCE
        if st is None or "geofence" not in st.failsafes:
            health |= mav.MAV_SYS_STATUS_GEOFENCE
        sent = sum(ln.sent for ln in c.links) or 1
        drops = sum(ln.dropped_telemetry for ln in c.links)
        errors = min(UINT16_MAX, sum(ln.bad_data for ln in c.links))
        return mav.MAVLink_sys_status_message(
            present, present, health, self.load_permille, UINT16_MAX, -1, -1,
            min(10000, int(10000 * drops / (sent + drops))), errors, 0, 0, 0, 0)

    def gps_raw_int(self, now: float) -> Any:
        """The receiver's fix: position of the newest fix; fix type (RTK float and
        fixed as 5 and 6), satellites, HDOP (``eph``, HDOP × 100) and altitude
        (mm above MSL) of the newest GGA/GNS of the last :data:`GPS_STALE_S`;
        speed and course of the newest velocity; ``h_acc``/``v_acc`` (mm) the
        1σ horizontal and vertical errors of the newest GST."""
        t_us = self.usec(now)
        if not self.core.cfg.devices.gps.enabled:
            return mav.MAVLink_gps_raw_int_message(t_us, mav.GPS_FIX_TYPE_NO_GPS,
                                                   0, 0, 0, UINT16_MAX, UINT16_MAX,
                                                   UINT16_MAX, UINT16_MAX, SATS_UNKNOWN)
        q = self.quality
        if q is not None and now - q.t > GPS_STALE_S:
            q = None
        sats = min(SATS_UNKNOWN - 1, q.num_sats) if q is not None and q.num_sats is not None \
            else SATS_UNKNOWN
        eph = (min(UINT16_MAX - 1, r_int(q.hdop * 100.0))
               if q is not None and q.hdop is not None else UINT16_MAX)
        g = self.fix
        if g is None or g.lat_deg is None or g.lon_deg is None \
                or not (math.isfinite(g.lat_deg) and math.isfinite(g.lon_deg)):
            return mav.MAVLink_gps_raw_int_message(t_us, mav.GPS_FIX_TYPE_NO_FIX,
                                                   0, 0, 0, eph, UINT16_MAX,
                                                   UINT16_MAX, UINT16_MAX, sats)
        if now - g.t > GPS_STALE_S:
            fix = mav.GPS_FIX_TYPE_NO_FIX
        else:
            fix = FIX_TYPE[q.fix if q is not None else g.fix]
        alt_m = q.alt_m if q is not None and q.alt_m is not None else g.alt_m
        vel = cog = UINT16_MAX
        v = self.vel.value
        if v is not None and now - v.t <= GPS_STALE_S:
            vel = min(UINT16_MAX - 1, r_int(v.sog_mps * 100.0))
            if v.cog_rad is not None:
                cog = r_int(math.degrees(v.cog_rad) * 100.0) % 36000
        h_acc = v_acc = 0  # unknown
        e = self.gst.value
        if e is not None and now - e.t <= GPS_STALE_S:
            if e.std_lat_m is not None and e.std_lon_m is not None:
                h_acc = min(0xFFFFFFFF, r_int(math.hypot(e.std_lat_m, e.std_lon_m) * 1000.0))
            if e.std_alt_m is not None:
                v_acc = min(0xFFFFFFFF, r_int(e.std_alt_m * 1000.0))
        return mav.MAVLink_gps_raw_int_message(
            t_us, fix, r_int(g.lat_deg * 1e7), r_int(g.lon_deg * 1e7),
            r_int((alt_m or 0.0) * 1000.0), eph, UINT16_MAX, vel, cog, sats,
            0, h_acc, v_acc)

    def global_position_int(self, now: float) -> Any:
        n = self.nav.value
        if n is None or not (math.isfinite(n.lat_deg) and math.isfinite(n.lon_deg)):
            return None
        alt = r_int(self.core.cfg.origin.alt_m * 1000.0)
        hdg = r_int(math.degrees(n.psi_rad) * 100.0) % 36000
        return mav.MAVLink_global_position_int_message(
            self.boot_ms(now), r_int(n.lat_deg * 1e7), r_int(n.lon_deg * 1e7),
            alt, 0, r_int(n.vn_mps * 100.0), r_int(n.ve_mps * 100.0), 0, hdg)

    def attitude(self, now: float) -> Any:
        n = self.nav.value
        if n is None:
            return None
        a = self.att.value
        roll = a.roll_rad if a is not None and a.roll_rad is not None else 0.0
        pitch = a.pitch_rad if a is not None and a.pitch_rad is not None else 0.0
        return mav.MAVLink_attitude_message(self.boot_ms(now), roll, pitch,
                                            math.remainder(n.psi_rad, math.tau), 0.0, 0.0,
                                            n.r_rps)

    def vfr_hud(self, now: float) -> Any:
        n = self.nav.value
        if n is None:
            return None
        c = self.thrust.value
        throttle = 0 if c is None else r_int(min(100.0, abs(c.u1 + c.u2) / 2.0))
        hdg = r_int(math.degrees(n.psi_rad)) % 360
        return mav.MAVLink_vfr_hud_message(n.u_mps, math.hypot(n.vn_mps, n.ve_mps), hdg,
                                           throttle, self.core.cfg.origin.alt_m, 0.0)

    def servo_output_raw(self, now: float) -> Any:
        c = self.thrust.value
        u1, u2 = (0.0, 0.0) if c is None else (c.u1, c.u2)
        return mav.MAVLink_servo_output_raw_message(
            int(now * 1e6) & 0xFFFFFFFF, 0, thrust_to_pwm(u1), thrust_to_pwm(u2),
            0, 0, 0, 0, 0, 0)

    def home_position(self, now: float) -> Any:
        c = self.core
        if c.home is None:
            return None
        lat, lon = c.home
        x, y = c.frame.to_ned(lat, lon)
        return mav.MAVLink_home_position_message(
            r_int(lat * 1e7), r_int(lon * 1e7),
            r_int(c.cfg.origin.alt_m * 1000.0), x, y, 0.0, [1.0, 0.0, 0.0, 0.0],
            0.0, 0.0, 0.0, self.usec(now))

    def autopilot_version(self) -> Any:
        caps = (mav.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
                | mav.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mav.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST)
        return mav.MAVLink_autopilot_version_message(
            caps, sw_version(), 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0,
            self.core.s.system_id)
