"""The MAVLink endpoint's parts, without a link: GPS_RTCM_DATA reassembly,
the thrust/PWM and joystick mappings, status texts, parameters (ranges,
choices, cross-field checks), mission items ↔ lines missions, settings."""

from __future__ import annotations

import math
import os
import random
from pathlib import Path

import pytest

from zarco_core.config import ConfigError, build
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import Mode
from zarco_runtime.guidance.mission import Mission, legs_from_points
from zarco_runtime.links.mavlink.mission import Item, items_from_mission, parse_items
from zarco_runtime.links.mavlink.params import INT32, REAL32, TABLE, ParamTable, f32
from zarco_runtime.links.mavlink.protocol import (
    ASCII,
    CUSTOM_MODE,
    STATUSTEXT_MAX_CHUNKS,
    STATUSTEXT_MAX_LEN,
    base_mode,
    mav,
    mix_manual,
    text_chunks,
    thrust_to_pwm,
)
from zarco_runtime.links.mavlink.rtcm import RtcmReassembler
from zarco_runtime.links.mavlink.settings import MavlinkSettings, read_signing_key
from zarco_runtime.settings import RuntimeConfig
from zarco_runtime.supervision.params import param_table

# ------------------------------------------------------------------ RTCM


def frags(block: bytes, seq: int, terminal: bool = False) -> list[tuple[int, bytes]]:
    """How a GCS cuts a block: QGroundControl (no empty last fragment) or, with
    ``terminal``, MAVProxy (an empty fragment after an exact multiple of 180)."""
    if len(block) < 180:
        return [((seq & 0x1F) << 3, block)]
    parts = [block[i:i + 180] for i in range(0, len(block), 180)]
    if terminal and len(block) % 180 == 0 and len(parts) < 4:
        parts.append(b"")
    return [(1 | (i << 1) | ((seq & 0x1F) << 3), p) for i, p in enumerate(parts)]


def feed_all(r: RtcmReassembler, msgs: list[tuple[int, bytes]], t: float = 0.0) -> list[bytes]:
    out: list[bytes] = []
    for flags, data in msgs:
        out += r.feed(flags, data, t)
    return out


def test_rtcm_blocks_of_every_size_come_out_whole_and_in_order() -> None:
    r = RtcmReassembler()
    blocks = [os.urandom(n) for n in (1, 60, 179, 181, 359, 500, 719)]
    out: list[bytes] = []
    for seq, b in enumerate(blocks):
        out += feed_all(r, frags(b, seq))
    assert out == blocks
    assert r.counters.blocks == len(blocks) and r.counters.bytes == sum(map(len, blocks))


def test_rtcm_exact_multiples_of_180_from_qgroundcontrol_and_mavproxy() -> None:
    # QGroundControl: full fragments only; the block is passed on when the next
    # one begins, or after flush_s without more
    r = RtcmReassembler(flush_s=0.2)
    b360, b540, b720, nxt = (os.urandom(n) for n in (360, 540, 720, 50))
    assert feed_all(r, frags(b360, 1)) == []
    assert feed_all(r, frags(nxt, 2)) == [b360, nxt]
    assert feed_all(r, frags(b540, 3), t=1.0) == []
    assert r.poll(1.1) == []
    assert r.poll(1.25) == [b540]
    assert feed_all(r, frags(b720, 4)) == [b720]  # four fragments: whole at once
    # MAVProxy: an empty fragment after them makes it whole at once
    r2 = RtcmReassembler()
    assert feed_all(r2, frags(b360, 5, terminal=True)) == [b360]


def test_rtcm_fragments_out_of_order_repeats_and_losses() -> None:
    r = RtcmReassembler()
    b = os.urandom(400)
    f = frags(b, 9)
    assert feed_all(r, [f[2], f[0], f[0], f[1]]) == [b]  # order does not matter
    assert r.counters.duplicates == 1
    # a block missing its middle fragment is dropped when the next block starts
    c = os.urandom(400)
    g = frags(c, 10)
    d = os.urandom(30)
    assert feed_all(r, [g[0], g[2]]) == []
    assert feed_all(r, frags(d, 11)) == [d]
    assert r.counters.fragments_dropped == 2
    # a fragment index seen again with other bytes starts the block again
    e = os.urandom(400)
    h = frags(e, 12)
    dropped = r.counters.fragments_dropped
    assert feed_all(r, [h[0], (h[0][0], os.urandom(180))]) == []
    assert r.counters.fragments_dropped == dropped + 1
    assert feed_all(r, [h[0], h[1], h[2]]) == [e]  # sent again: whole
    # longer than a fragment can be: refused
    assert r.feed(0, bytes(181), 0.0) == [] and r.counters.bad_length == 1


# ------------------------------------------------------------- mappings


def test_thrust_to_pwm_is_linear_1100_to_1900() -> None:
    assert [thrust_to_pwm(u) for u in (-100, -50, 0, 25, 100, 150)] == \
        [1100, 1300, 1500, 1600, 1900, 1900]
    assert thrust_to_pwm(float("nan")) == 1500


def test_joystick_mixing_x_forward_r_to_starboard() -> None:
    assert mix_manual(1000, 0) == (100.0, 100.0)
    assert mix_manual(0, 1000) == (100.0, -100.0)   # turn to starboard: port ahead
    assert mix_manual(500, 300) == (80.0, 20.0)
    assert mix_manual(-1000, -1000) == (-100.0, 0.0)
    assert mix_manual(32767, 32767) == (0.0, 0.0)   # invalid axes count as 0


def test_custom_modes_are_distinct_and_flags_follow_the_mode() -> None:
    assert len(set(CUSTOM_MODE.values())) == len(Mode)
    assert base_mode(Mode.LINES, True) & mav.MAV_MODE_FLAG_SAFETY_ARMED
    assert base_mode(Mode.LINES, True) & mav.MAV_MODE_FLAG_AUTO_ENABLED
    assert not base_mode(Mode.IDLE, False) & mav.MAV_MODE_FLAG_SAFETY_ARMED
    assert base_mode(Mode.MANUAL, True) & mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED


def test_status_texts_are_ascii_chunks_of_50() -> None:
    assert text_chunks("short") == [b"short"]
    long = "speed must be ≥ 0.05 m/s " * 5
    chunks = text_chunks(long)
    assert all(len(c) <= 50 for c in chunks) and len(chunks) == 3
    assert b"".join(chunks).decode("ascii") == long.replace("≥", ">=")
    exact = "x" * 100
    assert text_chunks(exact) == [b"x" * 50, b"x" * 50, b""]  # an empty chunk ends it


@pytest.mark.parametrize("n", [0, 1, 49, 50, 51, 449, 450, 451, 499, 500, 501, 12_799,
                               12_800, 12_801, 60_000, 1_000_000])
def test_status_texts_are_bounded_cut_with_an_ellipsis_and_always_pack(n: int) -> None:
    rng = random.Random(n)
    alphabet = "abc ≥°→€\x1b[31m\x00\n\t\x7f"
    text = "".join(rng.choice(alphabet) for _ in range(n))
    chunks = text_chunks(text)
    assert 1 <= len(chunks) <= STATUSTEXT_MAX_CHUNKS <= 256
    assert all(len(c) <= 50 for c in chunks)
    joined = b"".join(chunks)
    assert all(32 <= ch < 127 for ch in joined), joined  # printable ASCII only
    assert len(joined) <= STATUSTEXT_MAX_LEN
    # a chunk of 50 is never the last: a receiver knows where the text ends
    assert len(chunks[-1]) < 50
    spelt = text.translate(ASCII)
    if len(spelt) > STATUSTEXT_MAX_LEN:
        assert joined.endswith(b"...") and len(joined) == STATUSTEXT_MAX_LEN
    else:
        assert len(joined) == len(spelt.encode("ascii", "replace"))
    m = mav.MAVLink(None, 1, 1)
    for i, c in enumerate(chunks):  # every chunk packs, and parses back
        buf = mav.MAVLink_statustext_message(mav.MAV_SEVERITY_INFO, c, 7, i).pack(m)
        back = mav.MAVLink(None, 255, 190).parse_buffer(bytearray(buf))
        assert back is not None and back[0].text.encode() == c.rstrip(b"\0")


# ------------------------------------------------------------ parameters


def test_every_parameter_of_the_registry_has_an_id_and_no_id_writes() -> None:
    """Each parameter the supervisor lets change (but the polygon, which is no
    number) has one MAVLink id of at most 16 characters, and reading through the
    table reads the live configuration."""
    cfg = RuntimeConfig()
    t = ParamTable(cfg)
    assert len(t) == len(TABLE) and len({p.name for p in t.params}) == len(TABLE)
    assert all(len(p.name) <= 16 for p in t.params)
    numbers = {i.name for i in param_table(cfg) if i.kind != "points"}
    assert {p.key for p in t.params} == numbers
    kp = t.by_name["CTL_SPD_KP"]
    assert t.wire(kp) == cfg.control.speed_kp and kp.ptype == REAL32
    cfg.control.speed_kp = 45.0  # as the supervisor applies a change
    assert t.wire(kp) == 45.0


def test_received_values_become_the_registrys_types() -> None:
    rng = random.Random(7)
    t = ParamTable(RuntimeConfig())
    kp = t.by_name["CTL_SPD_KP"]
    for _ in range(50):
        x = f32(rng.uniform(-1e6, 1e6))
        assert f32(t.from_wire(kp, x)) == x  # the range is the supervisor's to judge
        # what a person types (up to 6 significant digits) is what the
        # configuration gets, not its float32 neighbour (0.1, not 0.100000001)
        typed = float(f"{rng.uniform(-1e3, 1e3):.{rng.randint(1, 6)}g}")
        assert t.from_wire(kp, f32(typed)) == typed
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(ValueError, match="not a number"):
            t.from_wire(kp, bad)
    d = t.by_name["CTL_LQR_D_M"]  # min 1e-4, not exact in float32: a bound sent back
    assert f32(1e-4) < 1e-4 and t.from_wire(d, f32(1e-4)) == 1e-4
    link = t.by_name["FS_LINK"]
    assert link.ptype == INT32 and t.wire(link) == 0.0
    assert [t.from_wire(link, float(i)) for i in range(3)] == ["shore", "mavlink", "any"]
    for bad in (3.0, -1.0, 0.5):
        with pytest.raises(ValueError):
            t.from_wire(link, bad)
    ff = t.by_name["CTL_CUR_FF"]
    assert ff.ptype == INT32 and t.wire(ff) == 1.0
    assert t.from_wire(ff, 0.0) is False and t.from_wire(ff, 1.0) is True
    with pytest.raises(ValueError, match="0 or 1"):
        t.from_wire(ff, 2.0)
    burst = t.by_name["SUP_CMD_BURST"]
    assert t.from_wire(burst, 20.0) == 20 and isinstance(t.from_wire(burst, 20.0), int)
    with pytest.raises(ValueError, match="whole"):
        t.from_wire(burst, 20.5)


# --------------------------------------------------------------- missions

WP = [(41.1851, -8.7050), (41.1852, -8.7050), (41.1852, -8.7048), (41.1851, -8.7048)]


def wp_item(seq: int, lat: float, lon: float,
            frame: int = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) -> Item:
    return Item(seq, frame, mav.MAV_CMD_NAV_WAYPOINT, x=lat, y=lon)


def speed_item(seq: int, s: float) -> Item:
    return Item(seq, mav.MAV_FRAME_MISSION, mav.MAV_CMD_DO_CHANGE_SPEED, 1.0, s, -1.0)


def test_waypoints_and_a_speed_make_a_lines_mission() -> None:
    items = [speed_item(0, 1.5)] + [wp_item(i + 1, *w) for i, w in enumerate(WP)]
    p = parse_items(items, 1.0)
    assert p.result == mav.MAV_MISSION_ACCEPTED
    assert p.waypoints == WP and p.speed_mps == 1.5 and p.wp_seqs == [1, 2, 3, 4]
    # without DO_CHANGE_SPEED: the configured speed; a speed between two
    # waypoints applies to the legs after it (here: all of them)
    assert parse_items([wp_item(i, *w) for i, w in enumerate(WP)], 0.7).speed_mps == 0.7
    mid = [wp_item(0, *WP[0]), speed_item(1, 2.0)] + [wp_item(i + 2, *w)
                                                       for i, w in enumerate(WP[1:])]
    assert parse_items(mid, 0.7).speed_mps == 2.0


def test_what_a_lines_mission_cannot_be_is_refused() -> None:
    two_speeds = [speed_item(0, 1.0), wp_item(1, *WP[0]), wp_item(2, *WP[1]),
                  speed_item(3, 2.0), wp_item(4, *WP[2])]
    p = parse_items(two_speeds, 1.0)
    assert p.result == mav.MAV_MISSION_UNSUPPORTED and "one speed" in p.reason
    local = [wp_item(0, *WP[0]), wp_item(1, 10.0, 5.0, frame=mav.MAV_FRAME_LOCAL_NED)]
    assert parse_items(local, 1.0).result == mav.MAV_MISSION_UNSUPPORTED_FRAME
    rtl = [wp_item(0, *WP[0]), wp_item(1, *WP[1]),
           Item(2, mav.MAV_FRAME_MISSION, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH)]
    p = parse_items(rtl, 1.0)
    assert p.result == mav.MAV_MISSION_UNSUPPORTED and "item 2" in p.reason
    assert parse_items([wp_item(0, *WP[0])], 1.0).result == mav.MAV_MISSION_INVALID
    assert parse_items([wp_item(0, *WP[0]), wp_item(1, 0.0, 0.0)], 1.0).result \
        == mav.MAV_MISSION_INVALID_PARAM5_X


def test_a_mission_from_elsewhere_downloads_as_items_that_parse_back() -> None:
    frame = LocalFrame(41.185, -8.705, 0.0)
    pts = [(0.0, 0.0), (50.0, 0.0), (50.0, 30.0)]
    m = Mission("lines", legs_from_points(pts, 1.2), "scenario")  # no geodetic waypoints
    items, seqs, _wps = items_from_mission(m, frame)
    back = parse_items(items, 9.9)
    assert back.result == mav.MAV_MISSION_ACCEPTED and back.speed_mps == 1.2
    assert back.wp_seqs == seqs
    for (lat, lon), (n, e) in zip(back.waypoints, pts, strict=True):
        bn, be = frame.to_ned(lat, lon)
        assert abs(bn - n) < 1e-6 and abs(be - e) < 1e-6


# --------------------------------------------------------------- settings


def test_settings_take_strings_lists_and_refuse_the_rest(tmp_path: Path) -> None:
    def mk(**kw: object) -> MavlinkSettings:
        return build(MavlinkSettings, dict(kw), "test.toml", "mavlink")

    assert mk(url="udpout:127.0.0.1:14550").urls() == ["udpout:127.0.0.1:14550"]
    assert mk(url=["tcpin:0.0.0.0:5760", "/dev/ttyUSB0,57600"]).urls() == \
        ["tcpin:0.0.0.0:5760", "/dev/ttyUSB0,57600"]
    for bad in ("udp://x:1", "udpout:host", "tcpin:0.0.0.0:70000", 5, [], ["a", 1]):
        with pytest.raises(ConfigError) as e:
            mk(url=bad)
        assert e.value.key == "mavlink.url"
    with pytest.raises(ConfigError, match="rates_hz"):
        mk(rates_hz={"ATTITUDE": 60.0})
    with pytest.raises(ConfigError, match="not a stream"):
        mk(rates_hz={"RAW_IMU": 5.0})
    key = os.urandom(32)
    (tmp_path / "raw.key").write_bytes(key)
    (tmp_path / "hex.key").write_text(key.hex() + "\n")
    (tmp_path / "short.key").write_bytes(key[:16])
    assert read_signing_key(str(tmp_path / "raw.key")) == key
    assert read_signing_key(str(tmp_path / "hex.key")) == key
    with pytest.raises(ConfigError) as e:
        mk(signing_key_file=str(tmp_path / "short.key"))
    assert e.value.key == "mavlink.signing_key_file"
    with pytest.raises(ConfigError, match="cannot read"):
        mk(signing_key_file=str(tmp_path / "missing.key"))


def test_the_documented_parameter_table_is_the_running_one() -> None:
    """docs/protocols.md lists every MAVLink parameter as the code has it."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "protocols.md").read_text()
    t = ParamTable(RuntimeConfig())
    rows = [ln for ln in doc.splitlines() if ln.startswith("| `") and "` | `" in ln
            and ln.split("`")[1] in t.by_name]
    assert rows == [t.describe(p) for p in t.params]
