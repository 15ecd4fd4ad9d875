"""The bridge against a fake firmware written from the protocol spec (tests/fake_firmware.py):
handshake or none, per-step replies, RC5, remote calls, several bots beside a Python controller,
and peers that stall, vanish, babble or flood. Every socket has a short timeout: nothing hangs."""

from __future__ import annotations

import math
import socket
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fake_firmware import FakeFirmware  # noqa: E402
from observers import FakeLive  # noqa: E402

from bots.behaviours import make  # noqa: E402
from bots.ctbot import CTBOT  # noqa: E402
from sim.bridge import (  # noqa: E402
    Bridge,
    Decoder,
    Packet,
    ProtocolError,
    parse_call,
    rc5_code,
    server,  # noqa: E402
)
from sim.bridge.firmware import MM_S_PER_UNIT, wheel_speed  # noqa: E402
from sim.bridge.firmware_map import window  # noqa: E402
from sim.bridge.protocol import remote_call_payload  # noqa: E402
from sim.run.loop import RobotSetup, run  # noqa: E402
from sim.views.recording.recorder import Recorder  # noqa: E402
from sim.world.files.grid import build_grid  # noqa: E402
from sim.world.spec import Movable, Start, Wall, WorldSpec, box  # noqa: E402

EMPTY = WorldSpec("empty", (-5.0, -5.0, 5.0, 5.0), starts=(Start(0.0, 0.0, 0.0, 1), Start(0.0, 1.0, 0.0, 2), Start(0.0, -1.0, 0.0, 0)))


def read_recording(path: Path) -> dict[str, dict[str, list]]:
    """Entity path -> column name -> values of the temporal chunks of a recording."""
    import pyarrow as pa
    import rerun.chunk

    found: dict[str, dict[str, list]] = {}
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        if not chunk.is_static:
            batch = chunk.to_record_batch()
            columns = found.setdefault(str(chunk.entity_path), {})
            for name in batch.schema.names:
                column = batch.column(name)
                columns.setdefault(name, []).extend((column.cast(pa.int64()) if pa.types.is_temporal(column.type) else column).to_pylist())
    return found


# --- packets ----------------------------------------------------------------------------------


def test_done_and_remote_call_bytes_match_the_traces():
    """Exact bytes from ctbot-protocol.md §3 and §8."""
    done = Packet("X", data_l=1000, seq=0x15, to=0x80)
    assert done.encode().hex(" ") == "3e 58 4e 00 e8 03 00 00 15 fe 80 3c"
    call = Packet("r", "O", seq=0x8A, to=0x80, payload=remote_call_payload("bot_turn", (90,)))
    assert call.encode().hex(" ") == "3e 72 4f 0d 00 00 00 00 8a fe 80 3c 62 6f 74 5f 74 75 72 6e 00 5a 00 00 00"
    motors = Decoder().feed(bytes.fromhex("3e 4d 4e 00 e7 ff 19 00 93 80 fe 3c"))
    assert motors == [Packet("M", "N", -25, 25, 0x93, 0x80, 0xFE)]


packets = st.builds(
    Packet,
    command=st.sampled_from("IEBLHTDmeRbSXWArqMlcOQ"),
    sub=st.sampled_from("NSROLEDCc"),
    data_l=st.integers(-32768, 32767),
    data_r=st.integers(-32768, 32767),
    seq=st.integers(0, 255),
    sender=st.integers(0, 255),
    to=st.integers(0, 255),
    payload=st.binary(max_size=255),
)


@given(st.lists(packets, max_size=8), st.integers(1, 40))
def test_decoder_round_trips_any_chunking(items, chunk):
    data = b"".join(p.encode() for p in items)
    decoder, out = Decoder(), []
    for i in range(0, len(data), chunk):
        out += decoder.feed(data[i : i + chunk])
    assert out == items and decoder.skipped == 0


def test_decoder_resyncs_after_junk_and_a_bad_stop_byte():
    good = Packet("M", data_l=3).encode()
    broken = bytearray(Packet("l").encode())
    broken[11] = ord("x")
    decoder = Decoder()
    assert decoder.feed(b"junk" + bytes(broken) + good) == [Packet("M", data_l=3)]
    assert decoder.skipped == 4 + 12 and decoder.problem


def test_calls_and_keys_parse_or_say_why():
    assert parse_call("bot_turn(90)") == ("bot_turn", (90,))
    assert parse_call("bot_goto_dist(200, 1)") == ("bot_goto_dist", (200, 1))
    assert parse_call("bot_solve_maze()") == ("bot_solve_maze", ())
    assert rc5_code("3") == 0x1183 and rc5_code("pwr") == 0x118C and rc5_code("0x1185") == 0x1185
    for bad in ("bot turn(1)", "bot_turn(x)", "bot_turn(90"):
        with pytest.raises(ValueError):
            parse_call(bad)
    with pytest.raises(ProtocolError, match="33"):
        parse_call("bot_goto_pos(1, 2, 3, 4, 5, 6)")  # 13 + 24 bytes: over the firmware's buffer
    with pytest.raises(ValueError, match="RC5"):
        rc5_code("HELP")


# --- runs -------------------------------------------------------------------------------------


def bridged(duration: float, fakes: dict | None = None, python: int = 0, step_timeout: float = 2.0, connect_timeout: float = 5.0, rc5=(), calls=(), recorder=None,
            bots: int = 1, welcome: bool = True, world: WorldSpec = EMPTY, like_ctsim: bool = True, list_calls: bool = False):  # fmt: skip
    """Run `bots` firmware bots (fakes with keyword options `fakes`) and `python` solve_maze
    robots in `world` (empty by default); returns (result, bridge, fakes)."""
    with Bridge(port=0, connect_timeout=connect_timeout, step_timeout=step_timeout, welcome=welcome, list_calls=list_calls) as bridge:
        setups = [bridge.setup(CTBOT, rc5=rc5, calls=calls, like_ctsim=like_ctsim) for _ in range(bots)]
        setups += [RobotSetup(CTBOT, make("solve_maze"), "solve_maze") for _ in range(python)]
        started = [FakeFirmware(bridge.listener.port, **(fakes or {})).start() for _ in range(bots)]
        observers = [bridge.observer(recorder)] + ([recorder] if recorder else [])
        result = run(world, setups, duration, observers=observers)
    for fake in started:
        fake.join()
        assert fake.error is None, fake.error
    return result, bridge, started


def test_handshake_gives_the_pool_address_and_every_later_packet_goes_to_it():
    result, bridge, (fake,) = bridged(0.5)
    assert result.reason == "duration" and bridge.bots[0].state.address == fake.address == 128
    targets = [[to for *_, to, _ in block] for block in fake.blocks]
    assert set(targets[0]) == {0xFF} and all(set(t) == {0x80} for t in targets[2:])
    assert fake.done_times[:3] == [-1, 20, 30]  # ms: c't-Sim's first block, then its 10 ms steps
    assert fake.shutdown  # SHUTDOWN at the end: the firmware exits 0


def test_without_a_handshake_the_bot_stays_at_the_broadcast_address():
    result, bridge, (fake,) = bridged(0.3, fakes={"handshake": False}, welcome=False)
    assert result.reason == "duration" and len(fake.blocks) == 30
    assert bridge.bots[0].state.address == 0xFF and not fake.welcomed


def test_rc5_key_3_drives_at_c_t_sims_speed_two_steps_later():
    """Key in block N -> M 75/75 in reply N+1 -> applied in motion N+2 (c't-Sim moves with the
    previous reply). 75 units are 131.8 mm/s, in c't-Sim's float32 arithmetic (`wheel_speed`):
    straight, the distance is exact."""
    result, _, _ = bridged(2.0, rc5=[(0.5, rc5_code("3"))])
    x = result.robots[0].truth_array()[:, 0]
    moving_from = 50 + 2  # steps
    expected = wheel_speed(75) * 0.01 * (200 - moving_from)
    assert x[moving_from] == 0.0 and x[-1] == pytest.approx(expected, abs=1e-9)  # float rounding only


def test_remote_bot_turn_finishes_with_result_1_near_90_degrees_and_is_recorded(tmp_path):
    """... and the firmware's log, LEDs and motors reach a live viewer as well as the file."""
    live = FakeLive()
    recorder = live.recorder(tmp_path / "run.rrd")
    result, bridge, _ = bridged(4.0, calls=[(0.2, "bot_turn(90)")], recorder=recorder)
    (call,) = bridge.summary()[0]["calls"]
    assert call["result"] == 1 and call["sent_step"] == 20 and call["done_step"] > call["sent_step"]
    heading = math.degrees(result.robots[0].truth_array()[-1, 2])
    assert heading == pytest.approx(90, abs=2)  # stops within a step or two of 0.52 deg each
    reported = result.robots[0].estimate_arrays()["reported"][-1]
    assert math.degrees(reported[2]) == pytest.approx(heading, abs=2)  # map packets: whole degrees
    recorded = read_recording(tmp_path / "run.rrd")
    assert "/firmware/ctbot/leds/orange" in recorded and "/firmware/ctbot/motors" in recorded
    texts = [str(v) for column in recorded["/firmware/ctbot/call"].values() for v in column]
    assert any("bot_turn finished with result 1" in t for t in texts)
    assert {path for path in recorded if path.startswith("/firmware/")} <= live.paths


def test_two_firmware_bots_beside_a_python_controller():
    result, bridge, fakes = bridged(1.0, python=1, bots=2, rc5=[(0.1, rc5_code("1"))])
    assert result.reason == "duration"
    assert sorted(f.address for f in fakes) == [128, 129]
    for log in result.robots[:2]:
        assert log.truth_array()[-1, 0] == pytest.approx(wheel_speed(25) * 0.01 * 88, abs=1e-9)
    assert result.robots[2].controller_name == "solve_maze"


@pytest.mark.parametrize(
    ("what", "message"),
    [
        ("stall", "no DONE from the firmware within 3 s"),
        ("vanish", "closed the connection"),
        ("garbage", "not packets"),
        ("foreign", "a motor packet from address 135 (0x87), not this bot's 128: refused"),
    ],
)
def test_a_bad_peer_ends_the_run_naming_bot_and_step_and_the_recording_stays(tmp_path, what, message):
    recorder = Recorder(tmp_path / "run.rrd")
    # 3 s: a healthy fake answers a step within milliseconds, even on a machine ten times slower
    result, _, _ = bridged(5.0, fakes={"misbehave": (30, what)}, step_timeout=3.0, recorder=recorder)
    assert result.reason == "error"
    assert "firmware bot 1" in result.error and message in result.error and "step 30" in result.error
    assert len(result.time) == 32  # samples 0..31 kept
    assert len(read_recording(tmp_path / "run.rrd")["/world/ctbot/body"]["sim_time"]) == 32


def test_a_flood_without_done_is_cut_off(monkeypatch):
    monkeypatch.setattr(server, "MAX_REPLY_BYTES", 1 << 16)
    result, _, _ = bridged(1.0, fakes={"misbehave": (5, "flood")}, step_timeout=5.0)
    assert result.reason == "error" and ("without a DONE" in result.error or "not packets" in result.error)


def test_a_bot_that_never_connects_is_named():
    with Bridge(port=0, connect_timeout=0.3) as bridge:
        result = run(EMPTY, [bridge.setup(CTBOT)], 1.0, observers=[bridge.observer()])
    assert result.reason == "error" and "no firmware connected" in result.error and "step 0" in result.error


def test_an_oversized_length_byte_never_crashes_the_link():
    """A header announcing 255 payload bytes swallows what follows; the step times out cleanly."""
    listener = server.Listener(port=0)
    peer = socket.create_connection(("127.0.0.1", listener.port), timeout=60)
    link = listener.accept(60.0)
    peer.sendall(struct.pack("<cBBBhhBBBc", b">", ord("l"), ord("N"), 255, 0, 0, 1, 0x80, 0xFE, b"<") + Packet("X").encode())
    with pytest.raises(server.LinkError, match="no DONE"):
        link.receive(0.3)
    peer.close()
    link.close()
    listener.close()


def test_the_listener_binds_loopback_only_by_default():
    with Bridge(port=0) as bridge:
        assert bridge.listener.host == "127.0.0.1"


def test_cli_bridge_runs_a_fake_firmware_and_writes_the_results(tmp_path, capsys):
    from sim.cli.entry import main

    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    fake = FakeFirmware(port).start()
    code = main(["bridge", str(Path(__file__).parents[1] / "worlds" / "square.toml"), "--port", str(port), "--duration", "3",
                 "--call", "0.5:bot_turn(90)", "--out", str(tmp_path), "--no-report", "--step-timeout", "2"])  # fmt: skip
    fake.join()
    out = capsys.readouterr().out
    assert code == 0 and "bot_turn(90) sent at step 50: result 1" in out
    import json

    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["bridge"][0]["calls"][0]["result"] == 1 and summary["bridge"][0]["address"] == 128


def test_cli_bridge_help_says_how_to_start_the_firmware(capsys):
    from sim.cli.entry import main

    with pytest.raises(SystemExit):
        main(["bridge", "--help"])
    assert "sleep infinity | /path/to/ct-Bot" in capsys.readouterr().out


@pytest.mark.parametrize("option", ["--rc5=x:3", "--rc5=1:HELP", "--call=1:bot turn", "--call=-1:bot_turn(9)"])
def test_cli_bad_timed_options_are_user_errors(option, capsys):
    from sim.cli.entry import main

    with pytest.raises(SystemExit) as exit_info:
        main(["bridge", "maze", option])
    assert exit_info.value.code == 2 and "ctsim: error:" in capsys.readouterr().err


def test_motor_units_are_c_t_sims_pwm_mapping():
    assert 75 * MM_S_PER_UNIT == pytest.approx(131.84, abs=0.01)  # ctbot-protocol.md §8: 75 -> 131.8 mm/s
    assert np.isclose(MM_S_PER_UNIT, 1.75788, atol=2e-4)  # the spec rounds 151/60 * 178.1283 / 255 = 1.75800
    for units in (25, 75, -200):  # c't-Sim's float32 speed: within float32's 6e-8 (a few roundings) of the exact one
        assert wheel_speed(units) * 1000 == pytest.approx(units * MM_S_PER_UNIT, rel=2e-7)


def test_mouse_sideways_sign_is_converted_at_the_protocol_edge():
    """ctsim's mouse counts are (forward, left); c't-Sim's dX points the other way, dY forward."""
    from bots.readings import Readings
    from sim.bridge.firmware import FirmwareController

    bot = FirmwareController(listener=None)
    block = Decoder().feed(bot._block(1, 0.01, Readings(), Readings(mouse_counts=np.array([10, 3]))))  # the dots of the motion after
    mouse = next(packet for packet in block if packet.command == "m")
    assert (mouse.data_l, mouse.data_r) == (-3, 10)


# --- c't-Sim to the step: numbers measured with the real c't-Sim 2.29.2 and the same firmware -----
# (../shared/tools/ctsim-reference: `bot_turn(90)` after RC5 3 at 0.5 s and PWR at 5.5 s in
# freie-flaeche.xml, and RC5 3 into the wall of winzig.xml; proxy logs and c't-Sim's pose trace)


def sent(fake: FakeFirmware, command: str) -> list[tuple[int, int]]:
    """(data_l, data_r) of the first `command` packet in each block the fake received."""
    return [next((dl, dr) for cmd, _, dl, dr, _, _ in block if cmd == command) for block in fake.blocks]


def test_the_first_block_is_c_t_sims_from_before_its_first_step():
    """c't-Sim sends a block before its first step: every sensor 0 but the error sensor 1, DONE -1
    (the firmware's clock starts at -11 ms for it: timer-low_pc.c); its second block has DONE 20."""
    _, _, (fake,) = bridged(0.1)
    first = {cmd: (dl, dr) for cmd, _, dl, dr, _, _ in fake.blocks[0]}
    assert first == {**{cmd: (0, 0) for cmd in "mDBHIRTLESb"}, "e": (1, 0), "X": (-1, 0)}
    assert sent(fake, "e")[1] == (1, 0) and sent(fake, "I")[1] == (100, 80)  # c't-Sim: error sensor data_r 0


def test_encoder_ticks_and_the_rc5_toggle_arrive_in_c_t_sims_blocks():
    """Key 3 in block 50, M 75/75 in reply 51, the first motion in step 52: c't-Sim sends that
    motion's ticks in block 52 itself, so the first tick (0.444 a step) is in block 54, and the
    151st at the exact 340-step boundary in block 391 (its float32 speed is a hair fast). The
    RC5 toggle bit flips with each key and stays in every block: 1 from block 50, 0 from the
    PWR key in block 550."""
    _, _, (fake,) = bridged(6.0, rc5=[(0.5, rc5_code("3")), (5.5, rc5_code("PWR"))])
    ticks = sent(fake, "E")
    assert ticks[:54] == [(0, 0)] * 54 and ticks[54] == (1, 1)
    assert ticks[390:393] == [(0, 0), (1, 1), (0, 0)] and sum(t[0] for t in ticks[:392]) == 151
    rc5 = sent(fake, "R")
    assert rc5[:50] == [(0, 0)] * 50 and rc5[50] == (0x1183, 1) and set(rc5[51:550]) == {(0, 1)}
    assert rc5[550] == (0x118C, 0) and set(rc5[551:]) == {(0, 0)}


def test_remote_bot_turn_ends_in_c_t_sims_step():
    """The fake turns at -25/25 from its reply to the order (block 20, motion from step 21) until
    its encoder heading reaches 90 deg: 26 ticks a wheel (2.9688 mm each, 97.2 mm track) at 151/1020
    ticks a step (25 units), so the 26th tick comes with the 176th step of motion, step 196, and
    so does the r/D, as in c't-Sim (a tick a block late ends the turn a step late: 197)."""
    ticks_needed = math.ceil((math.pi / 2) / (2 * 178.1283 / 60 / 97.2))
    steps = math.ceil(ticks_needed * 1020 / 151)
    _, bridge, _ = bridged(4.0, calls=[(0.2, "bot_turn(90)")])
    assert ticks_needed == 26 and bridge.summary()[0]["calls"][0]["done_step"] == 20 + steps == 196


WINZIG_WALL = 1.44  # winzig.xml: the face of the top wall row, 6 cells of 0.24 m up


def test_a_firmware_bot_stops_where_c_t_sims_does():
    """RC5 3 at 0.5 s towards a wall 1.08 m ahead (winzig.xml): c't-Sim stops the bot at its last
    position clear of the wall, y = 1.379200 m (its trace, 6 decimals), 60.8 mm before the face,
    and the wheels go on turning; ctsim's own contacts take it 1.3 mm (a step) further."""
    world = WorldSpec("winzig-like", (0.0, 0.0, 1.2, 1.68), walls=(Wall(box(0.0, WINZIG_WALL, 1.2, 1.68)),), starts=(Start(0.36, 0.36, math.pi / 2, 1),))
    result, _, (fake,) = bridged(12.0, rc5=[(0.5, rc5_code("3"))], world=world)
    x, y, heading = result.robots[0].truth_array()[-1]
    assert y == pytest.approx(1.379200, abs=5e-7) and x == 0.36 and heading == math.pi / 2  # the trace's rounding
    assert result.robots[0].collisions == 1 and sum(left for left, _ in sent(fake, "E")[-9:]) >= 3  # 0.444 ticks a step go on
    own, _, _ = bridged(12.0, rc5=[(0.5, rc5_code("3"))], world=world, like_ctsim=False)
    assert own.robots[0].truth_array()[-1, 1] > 1.379200 + 0.001


def test_list_calls_asks_once_and_records_the_offer():
    _, bridge, _ = bridged(0.3, list_calls=True)
    bot = bridge.bots[0]
    assert bot.state.functions == ["bot_turn(int16 degrees)"] and bot.state.functions_complete
    assert [e.text for e in bot.events if e.kind == "call"] == ["offers bot_turn(int16 degrees)"]


def test_the_firmware_map_is_drawn_where_the_firmware_believes_it_drove(tmp_path):
    """The fake marks the map cell under its encoder pose; the bridge puts the block together,
    places it by the start pose and records it under world/map/firmware/<robot>."""
    recorder = Recorder(tmp_path / "run.rrd")
    start = Start(1.0, -2.0, math.radians(30), 1)
    world = WorldSpec("open", (-5.0, -5.0, 5.0, 5.0), starts=(start,))
    result, bridge, (fake,) = bridged(2.0, rc5=[(0.1, rc5_code("3"))], recorder=recorder, world=world)
    fw_map = bridge.bots[0].state.map
    assert fw_map.blocks > 0 and fw_map.dropped == 0
    (x, y), = np.argwhere(fw_map.cells == 100)[-1:]  # the last cell the fake marked
    cells = window(world.bounds, (start.x, start.y, start.heading))
    corner, matrix = fw_map.placement((start.x, start.y, start.heading), cells)
    u, v = x - cells[0] + 0.5, y - cells[1] + 0.5  # the cell's centre in the image
    world_xy = np.array(corner[:2]) + np.array(matrix)[:2, :2] @ (u, v)
    truth = result.robots[0].truth_array()
    assert np.min(np.hypot(*(truth[:, :2] - world_xy).T)) < 0.006  # within a cell (8 mm square)
    recorded = read_recording(tmp_path / "run.rrd")
    assert "/world/map/firmware/ctbot" in recorded


def test_shutdown_comes_after_the_files_are_written_and_list_calls_prints_the_offer(tmp_path, capsys):
    from sim.cli.entry import main

    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    written = []
    fake = FakeFirmware(port, on_shutdown=lambda: written.append(sorted(p.name for p in tmp_path.iterdir()))).start()
    code = main(["bridge", str(Path(__file__).parents[1] / "worlds" / "square.toml"), "--port", str(port), "--duration", "0.5",
                 "--out", str(tmp_path), "--step-timeout", "2", "--list-calls"])  # fmt: skip
    fake.join()
    assert code == 0 and fake.shutdown
    assert {"summary.json", "run.rrd"} <= set(written[0]) and any(name.endswith(".png") for name in written[0])
    assert "firmware bot 1 offers 1 remote calls:\n  bot_turn(int16 degrees)" in capsys.readouterr().out


def test_a_firmware_silent_on_the_last_block_leaves_a_complete_run():
    """The block of the last step goes out after the run (`finish`): a firmware that never answers
    it costs one step timeout and an event, not the run."""
    result, bridge, (fake,) = bridged(0.5, fakes={"misbehave": (49, "stall")}, step_timeout=0.5)
    assert result.reason == "duration" and len(fake.blocks) == 50
    assert any("no reply to the last block" in e.text for e in bridge.bots[0].events)


def test_cli_bridge_is_exact_unless_asked_and_run_keeps_its_noise(capsys):
    """c't-Sim's wheels and sensors are exact: the bridge's --noise is none by default (said in
    its --help), every other command keeps realistic noise as its default."""
    from sim.cli.entry import build_parser

    parser = build_parser()
    assert parser.parse_args(["bridge"]).noise == "none" and parser.parse_args(["bridge", "--noise", "realistic"]).noise == "realistic"
    assert parser.parse_args(["run"]).noise == "realistic"
    with pytest.raises(SystemExit):
        parser.parse_args(["bridge", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "Exact unless asked" in text and "(default: none)" in text


def test_a_can_stops_a_firmware_bot_where_c_t_sims_contact_test_does():
    """RC5 3 towards a can (Java3D's 15-sided cylinder of 30 mm, a corner due north; its box reaches
    15 cos 12° = 14.67 mm south of its centre): c't-Sim stops the bot when its 60 mm sphere would
    meet that box, at the last step before y + 0.06 reaches 0.8 - 0.014672 (ctsim's own contacts
    push the can on)."""
    can = Movable((0.36, 0.8))
    world = WorldSpec("can", (0.0, 0.0, 1.2, 1.68), movables=(can,), starts=(Start(0.36, 0.36, math.pi / 2, 1),))
    result, _, _ = bridged(8.0, rc5=[(0.5, rc5_code("3"))], world=world)
    y = result.robots[0].truth_array()[-1, 1]
    contact = 0.8 - 0.015 * math.cos(math.pi / 15) - 0.06
    assert contact - wheel_speed(75) * 0.01 < y < contact  # within the last step of 1.318 mm before it



def test_a_lamp_pillar_stops_a_firmware_bot_at_the_box_round_it():
    """RC5 3 past a lamp pillar as the bridge loads it (c't-Sim's 0.1 m, 15-sided cylinder) 40 mm
    to the side of the bot's path: c't-Sim's contact test meets the box round the pillar, whose
    south face lies 50 cos 12° = 48.9 mm south of its centre over the whole path's width, so the bot
    stops within a step before y + 0.06 reaches it; the polygon itself comes 7.5 mm later."""
    pillar = build_grid(["*"], pillars="cylinder", origin=(0.40 - 0.12, 0.8 - 0.12)).walls
    world = WorldSpec("pillar", (0.0, 0.0, 1.2, 1.68), walls=pillar, starts=(Start(0.36, 0.36, math.pi / 2, 1),))
    result, _, _ = bridged(8.0, rc5=[(0.5, rc5_code("3"))], world=world)
    y = result.robots[0].truth_array()[-1, 1]
    contact = 0.8 - 0.05 * math.cos(math.pi / 15) - 0.06
    assert pillar[0].cylinder and contact - wheel_speed(75) * 0.01 < y < contact
