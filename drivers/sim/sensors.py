"""Pure emitters of the simulated devices: truth in, NMEA bytes out.

No I/O and no clocks: each emitter is called with the simulation time
``t_s`` (seconds since the start of the run) and the truth, draws its noise
from its own normal stream and returns complete sentences (``$...*hh\\r\\n``)
framed by :func:`drivers.nmea.format_sentence`.  Every call draws the same
number of variates whatever the mode or the sentence list, so changing a fix
mode or a sentence list never shifts the noise of later epochs.

* :class:`SimGps`: GGA / RMC / VTG at the receiver rate, GST and ZDA at their
  own rates.
* :class:`SimCompass`: HDG (magnetic, with variation), ROT, XDR pitch/roll.
* :class:`SimThrusterController`: the ``$PZTHR`` watchdog and ``$PZTHS`` status
  (docs/protocols.md).
"""

from __future__ import annotations

import math
from datetime import date, timedelta

import numpy as np

from drivers.nmea import format_sentence
from drivers.sim.disturbance import GaussMarkov, NormalStream
from drivers.sim.params import FIX_MODES, CompassParams, GpsParams, ThrusterParams
from drivers.sim.thruster_model import U_MAX
from zarco_core.localgeo import FastLocalFrame

#: metres per second in one knot (1852 m per hour)
KNOT_MPS = 1852.0 / 3600.0
#: docs/protocols.md: the thruster controller stops when no valid $PZTHR came for this long (s)
WATCHDOG_S = 0.5

#: GGA quality indicator of each fix mode (NMEA 0183: 4 RTK fixed, 5 RTK float)
GGA_QUALITY = {"none": 0, "single": 1, "dgps": 2, "rtk_fixed": 4, "rtk_float": 5}
#: RMC/VTG FAA mode indicator of each fix mode
FAA_MODE = {"none": "N", "single": "A", "dgps": "D", "rtk_fixed": "R", "rtk_float": "F"}

_EPOCH = date(1970, 1, 1)


# ---------------------------------------------------------------- formatting


def utc_fields(utc_epoch_s: float) -> tuple[str, date]:
    """(``hhmmss.ss``, date) of a UTC time in seconds since 1970, rounded to 10 ms
    once, so the time and the date always agree (no ``60.00`` seconds)."""
    cs = round(utc_epoch_s * 100.0)
    days, rem = divmod(cs, 8_640_000)
    hh, rem = divmod(rem, 360_000)
    mm, rem = divmod(rem, 6_000)
    ss, cc = divmod(rem, 100)
    return f"{hh:02d}{mm:02d}{ss:02d}.{cc:02d}", _EPOCH + timedelta(days=days)


def format_lat(lat_deg: float) -> tuple[str, str]:
    """Latitude as (``ddmm.mmmmmmmm``, ``N``|``S``): 1e-8 minute ≈ 19 µm."""
    units = round(abs(lat_deg) * 6e9)  # 1e-8 arc minutes, integer: exact carries
    deg, rem = divmod(units, 6_000_000_000)
    mins, frac = divmod(rem, 100_000_000)
    return f"{deg:02d}{mins:02d}.{frac:08d}", ("N" if lat_deg >= 0.0 else "S")


def format_lon(lon_deg: float) -> tuple[str, str]:
    """Longitude as (``dddmm.mmmmmmmm``, ``E``|``W``)."""
    units = round(abs(lon_deg) * 6e9)
    deg, rem = divmod(units, 6_000_000_000)
    mins, frac = divmod(rem, 100_000_000)
    return f"{deg:03d}{mins:02d}.{frac:08d}", ("E" if lon_deg >= 0.0 else "W")


def _fmt(x: float, decimals: int) -> str:
    """Fixed-point text without a negative zero."""
    s = f"{x:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def _wrap360(deg: float, decimals: int) -> str:
    """An angle in [0, 360) as text, wrapped after rounding (359.96 → ``0.0``)."""
    x = round(deg % 360.0, decimals)
    if x >= 360.0:
        x -= 360.0
    return _fmt(x, decimals)


class NedToGeodetic(FastLocalFrame):
    """Local NED (m) about a geodetic origin → WGS-84 latitude/longitude (deg),
    as a callable: the runtime's plain-math local frame
    (:class:`zarco_core.localgeo.FastLocalFrame`, checked against
    pymap3d in the tests), which costs a few µs where pymap3d costs ~120."""

    __slots__ = ()

    def __call__(self, north_m: float, east_m: float, down_m: float = 0.0
                 ) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, h_m) of a local point."""
        return self.to_geodetic(north_m, east_m, down_m)


def _due(t_s: float, rate_hz: float, last: int) -> int | None:
    """Index of the rate's period containing ``t_s`` if a sentence is due (first
    call, or a new period since ``last``), else None."""
    if rate_hz <= 0.0:
        return None
    idx = math.floor(t_s * rate_hz + 1e-6)
    return idx if idx > last else None


# ----------------------------------------------------------------------- GPS


class SimGps:
    """RTK GNSS receiver: NMEA position, velocity, error statistics and time.

    Position error per horizontal axis (N, E), 1σ from :class:`GpsParams`:

    ========== ======================= ==========================
    fix        white                   plus drifting bias
    ========== ======================= ==========================
    rtk_fixed  ``sigma_rtk_fixed_m``   none
    rtk_float  ``sigma_rtk_float_m``   ``float_bias_m`` (τ ``float_bias_tau_s``)
    dgps       ``sigma_dgps_m``        none
    single     ``sigma_single_m``      ``single_bias_m`` (τ ``single_bias_tau_s``)
    none       no position             —
    ========== ======================= ==========================

    Both biases are Gauss–Markov processes that run in every mode, so a fix
    change (:meth:`set_fix`) shows as the jump a real receiver makes.  The
    altitude gets white noise of twice the horizontal σ (typical vertical DOP).
    Velocity: true ground velocity + white N/E noise ``speed_sigma_mps``, shown
    as SOG (knots) and COG (degrees true).  The antenna is at the centre of mass.
    """

    def __init__(self, params: GpsParams, origin: tuple[float, float] | tuple[float, float, float],
                 rng: np.random.Generator) -> None:
        if params.fix not in FIX_MODES:
            raise ValueError(f"unknown fix mode {params.fix!r}")
        self.p = params
        self.fix = params.fix
        self.to_geodetic = NedToGeodetic(*origin)
        self.normals = NormalStream(rng)
        nrm = self.normals
        self.single_bias = (GaussMarkov(params.single_bias_m, params.single_bias_tau_s, nrm),
                            GaussMarkov(params.single_bias_m, params.single_bias_tau_s, nrm))
        self.float_bias = (GaussMarkov(params.float_bias_m, params.float_bias_tau_s, nrm),
                           GaussMarkov(params.float_bias_m, params.float_bias_tau_s, nrm))
        self._last_t: float | None = None
        self._gst_last = -(2**62)
        self._zda_last = -(2**62)
        #: the last position error (north, east) in metres, for tests and plots
        self.last_error_ne: tuple[float, float] = (0.0, 0.0)

    def set_fix(self, mode: str) -> None:
        """Change the fix mode (``none``, ``single``, ``dgps``, ``rtk_float``, ``rtk_fixed``)."""
        if mode not in FIX_MODES:
            raise ValueError(f"unknown fix mode {mode!r}, expected one of {list(FIX_MODES)}")
        self.fix = mode

    def sigma_m(self, mode: str | None = None) -> float:
        """Total 1σ horizontal error per axis (white and bias, m) of a fix mode."""
        p = self.p
        match mode or self.fix:
            case "rtk_fixed":
                return p.sigma_rtk_fixed_m
            case "rtk_float":
                return math.hypot(p.sigma_rtk_float_m, p.float_bias_m)
            case "dgps":
                return p.sigma_dgps_m
            case "single":
                return math.hypot(p.sigma_single_m, p.single_bias_m)
        return math.nan

    def sentences(self, t_s: float, utc_epoch_s: float, true_x: float, true_y: float,
                  vn: float, ve: float) -> bytes:
        """One receiver epoch at time ``t_s`` (s) for the true position (north,
        east m) and true ground velocity (north, east m/s): the configured
        rate sentences plus GST/ZDA when due, concatenated."""
        p = self.p
        dt = 0.0 if self._last_t is None else max(0.0, t_s - self._last_t)
        self._last_t = t_s
        nrm = self.normals.next
        # fixed draw order and count per epoch: biases (4), white N/E/D (3), speed (2)
        sb_n = self.single_bias[0].step(dt)
        sb_e = self.single_bias[1].step(dt)
        fb_n = self.float_bias[0].step(dt)
        fb_e = self.float_bias[1].step(dt)
        w_n, w_e, w_d = nrm(), nrm(), nrm()
        s_n, s_e = nrm(), nrm()

        mode = self.fix
        if mode == "rtk_fixed":
            sig, en, ee = p.sigma_rtk_fixed_m, 0.0, 0.0
        elif mode == "rtk_float":
            sig, en, ee = p.sigma_rtk_float_m, fb_n, fb_e
        elif mode == "dgps":
            sig, en, ee = p.sigma_dgps_m, 0.0, 0.0
        elif mode == "single":
            sig, en, ee = p.sigma_single_m, sb_n, sb_e
        else:
            sig, en, ee = 0.0, 0.0, 0.0
        en += sig * w_n
        ee += sig * w_e
        self.last_error_ne = (en, ee)

        tm, day = utc_fields(utc_epoch_s)
        tk = p.talker
        valid = mode != "none"
        out: list[bytes] = []
        if valid:
            lat, lon, _h = self.to_geodetic(true_x + en, true_y + ee)
            la, ns = format_lat(lat)
            lo, ew = format_lon(lon)
            alt = _fmt(p.alt_m + 2.0 * sig * w_d, 3)
            mvn, mve = vn + p.speed_sigma_mps * s_n, ve + p.speed_sigma_mps * s_e
            sog_kn = math.hypot(mvn, mve) / KNOT_MPS
            cog = math.degrees(math.atan2(mve, mvn))
            sog_s, cog_s = _fmt(sog_kn, 3), _wrap360(cog, 2)
        else:
            la = ns = lo = ew = alt = sog_s = cog_s = ""
            sog_kn = 0.0
        faa = FAA_MODE[mode]
        for name in p.sentences:
            if name == "GGA":
                if valid:
                    diff = ("1.0", "0000") if mode != "single" else ("", "")
                    body = (f"{tk}GGA,{tm},{la},{ns},{lo},{ew},{GGA_QUALITY[mode]},"
                            f"{p.num_sats:02d},{p.hdop:.1f},{alt},M,0.000,M,{diff[0]},{diff[1]}")
                else:
                    body = f"{tk}GGA,{tm},,,,,0,00,99.9,,M,,M,,"
                out.append(format_sentence(body))
            elif name == "RMC":
                status = "A" if valid else "V"
                ddmmyy = f"{day.day:02d}{day.month:02d}{day.year % 100:02d}"
                out.append(format_sentence(
                    f"{tk}RMC,{tm},{status},{la},{ns},{lo},{ew},{sog_s},{cog_s},{ddmmyy},,,{faa}"))
            elif name == "VTG":
                kmh = _fmt(sog_kn * 1.852, 3) if valid else ""
                out.append(format_sentence(
                    f"{tk}VTG,{cog_s},T,,M,{sog_s},N,{kmh},K,{faa}"))
        idx = _due(t_s, p.gst_rate_hz, self._gst_last)
        if idx is not None:
            self._gst_last = idx
            if valid:
                s = self.sigma_m(mode)
                v = _fmt(s, 3)
                body = f"{tk}GST,{tm},{v},{v},{v},0.0,{v},{v},{_fmt(2.0 * s, 3)}"
            else:
                body = f"{tk}GST,{tm},,,,,,,"
            out.append(format_sentence(body))
        idx = _due(t_s, p.zda_rate_hz, self._zda_last)
        if idx is not None:
            self._zda_last = idx
            out.append(format_sentence(
                f"{tk}ZDA,{tm},{day.day:02d},{day.month:02d},{day.year:04d},00,00"))
        return b"".join(out)


# ------------------------------------------------------------- compass / IMU


class SimCompass:
    """Magnetic compass with rate gyro and pitch/roll sensor.

    * HDG (talker ``HC``): magnetic heading = true − variation + bias + white
      noise (``noise_deg``), deviation empty, variation field filled
      (``2.0,W`` for −2°), so true = magnetic + variation (east positive).
    * ROT (talker ``TI``): rate of turn in °/min, positive when the bow turns
      to starboard, = r + turn-on bias + white noise, status ``A``.
    * XDR (talker ``YX``): ``$YXXDR,A,<pitch>,D,PTCH,A,<roll>,D,ROLL`` in
      degrees, pitch bow-up and roll starboard-down positive, + white noise.

    Gyro noise discretisation: the density ``N`` (rad/s/√Hz) is a one-sided
    amplitude spectral density, as data sheets give it.  A gyro read at
    ``f_s = rate_hz`` is band-limited to the Nyquist band (its anti-alias /
    averaging filter; for a boxcar average over 1/f_s the one-sided noise
    bandwidth is exactly f_s/2), so the per-sample white noise has variance
    N² · f_s/2, i.e. σ = N √(f_s/2) (20 Hz: 1.08e-3 rad/s ≈ 3.7 °/min).  (The
    two-sided, Allan-variance convention used e.g. by Kalibr gives N √f_s,
    √2 larger.)  The turn-on bias has magnitude ``gyro_bias_dps`` and a sign
    drawn from this sensor's stream at construction, fixed for the run.
    """

    def __init__(self, params: CompassParams, rng: np.random.Generator) -> None:
        self.p = params
        self.normals = NormalStream(rng)
        sign = 1.0 if self.normals.next() >= 0.0 else -1.0
        #: turn-on gyro bias (rad/s), fixed for the run
        self.gyro_bias_rps = sign * math.radians(params.gyro_bias_dps)
        #: white gyro noise per sample (rad/s)
        self.gyro_sigma_rps = params.gyro_noise_density_rps_rthz * math.sqrt(params.rate_hz / 2)
        var = params.variation_deg
        self._var_field = f"{abs(var):.1f},{'E' if var >= 0.0 else 'W'}"
        self._epoch = 0

    def sentences(self, t_s: float, psi_true_rad: float, r_true_rps: float,
                  pitch_rad: float = 0.0, roll_rad: float = 0.0) -> bytes:
        """HDG, ROT and XDR for the true heading (rad, clockwise from north),
        yaw rate (rad/s, clockwise) and attitude (rad) at time ``t_s``."""
        p = self.p
        nrm = self.normals.next
        n_h, n_g, n_p, n_r = nrm(), nrm(), nrm(), nrm()
        mag = math.degrees(psi_true_rad) - p.variation_deg + p.bias_deg + p.noise_deg * n_h
        rot = math.degrees(r_true_rps + self.gyro_bias_rps + self.gyro_sigma_rps * n_g) * 60.0
        pitch = math.degrees(pitch_rad) + p.pitch_noise_deg * n_p
        roll = math.degrees(roll_rad) + p.roll_noise_deg * n_r
        out = (format_sentence(f"HCHDG,{_wrap360(mag, 1)},,,{self._var_field}")
               + format_sentence(f"TIROT,{_fmt(rot, 2)},A"))
        self._epoch += 1
        if (self._epoch - 1) % p.xdr_every == 0:
            out += format_sentence(f"YXXDR,A,{_fmt(pitch, 1)},D,PTCH,A,{_fmt(roll, 1)},D,ROLL")
        return out


# ------------------------------------------------------- thruster controller


class SimThrusterController:
    """The thruster controller board as a pure state machine (docs/protocols.md).

    :meth:`on_command` is called for each valid ``$PZTHR``; commands are
    clamped to −100..100.  :meth:`outputs` returns the commands being applied:
    zero until the first command and once no valid command has arrived for
    ``watchdog_s`` (0.5 s; the boundary counts as expired).

    Status model for ``$PZTHS`` (from the actual, lagged thrust F of each
    thruster and its own full-scale thrust F_max = (1 ± mismatch) · 125 N
    forward or 75 N reverse): propeller thrust grows with the square of its
    speed, so RPM = sign(F) · rpm_max · √(|F|/F_max); shaft power grows with the
    cube of the speed and the bus voltage is constant, so the motor current is
    A = amps_max_a · (|F|/F_max)^1.5.
    """

    def __init__(self, params: ThrusterParams, watchdog_s: float = WATCHDOG_S) -> None:
        self.p = params
        self.watchdog_s = watchdog_s
        self.last_cmd_t = -math.inf
        self.u1 = 0.0
        self.u2 = 0.0

    def on_command(self, t_s: float, u1: float, u2: float) -> bool:
        """A ``$PZTHR`` arrived at ``t_s``; False (and ignored) if not finite."""
        if not (math.isfinite(u1) and math.isfinite(u2)):
            return False
        self.u1 = min(U_MAX, max(-U_MAX, u1))
        self.u2 = min(U_MAX, max(-U_MAX, u2))
        self.last_cmd_t = t_s
        return True

    def outputs(self, t_s: float) -> tuple[float, float]:
        """Commands (U1, U2) applied to the thrusters at ``t_s``."""
        if t_s - self.last_cmd_t >= self.watchdog_s - 1e-9:
            return (0.0, 0.0)
        return (self.u1, self.u2)

    def _rpm_amps(self, f_n: float, scale: float) -> tuple[int, float]:
        full = scale * (self.p.fwd_max_n if f_n >= 0.0 else self.p.rev_max_n)
        x = min(1.0, abs(f_n) / full) if full > 0.0 else 0.0
        rpm = round(math.copysign(self.p.rpm_max * math.sqrt(x), f_n))
        return rpm, self.p.amps_max_a * x ** 1.5

    def status_sentence(self, t_s: float, f1_n: float, f2_n: float) -> bytes:
        """``$PZTHS,U1,U2,RPM1,RPM2,A1,A2*hh`` for the actual thrusts (N)."""
        u1, u2 = self.outputs(t_s)
        rpm1, a1 = self._rpm_amps(f1_n, 1.0 + self.p.mismatch)
        rpm2, a2 = self._rpm_amps(f2_n, 1.0 - self.p.mismatch)
        return format_sentence(f"PZTHS,{_fmt(u1, 1)},{_fmt(u2, 1)},{rpm1:d},{rpm2:d},"
                               f"{a1:.1f},{a2:.1f}")
