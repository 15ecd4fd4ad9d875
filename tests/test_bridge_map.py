"""The firmware's own map from its MAP packets (sim/bridge/firmware_map.py): block addresses as the
firmware computes them (map.c `get_block`, restated here from its description in
ctbot-protocol.md and the firmware's map layout), four parts to a block, the image and where it
lies in the world."""

from __future__ import annotations

import io
import math
import struct

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sim.bridge.firmware_map import CELL_M, CELLS, FirmwareMap, block_origin, window
from sim.bridge.protocol import Packet
from sim.views.map_image import rgba_png


def firmware_block(x: int, y: int) -> int:
    """The block holding map cell (x, y): 512-cell macroblocks three to a row; inside one, blocks
    of two 16 x 16 sections along x, 16 blocks to a row of 16 cells."""
    local = (x % 512) // 32 + ((y % 512) // 16) * 16
    return local + (x // 512 + (y // 512) * 3) * 512


def parts(block: int, data: bytes) -> list[Packet]:
    return [Packet("Q", sub, block, 0, payload=data[k * 128 : (k + 1) * 128]) for k, sub in enumerate("DEFG")]


@given(st.integers(0, CELLS - 1), st.integers(0, CELLS - 1))
def test_a_block_starts_at_the_cell_the_firmware_files_it_under(x, y):
    bx, by = block_origin(firmware_block(x, y))
    assert bx <= x < bx + 32 and by <= y < by + 16 and bx % 32 == 0 and by % 16 == 0


def test_a_block_of_four_parts_fills_its_cells_x_major():
    """Byte (x % 32) * 16 + y % 16 of a block is cell (x, y) (two sections, each [x][y])."""
    fw_map = FirmwareMap()
    x, y = 770, 1000
    data = bytearray(512)
    data[(x % 32) * 16 + y % 16] = 0x9C  # -100: an obstacle
    for packet in parts(firmware_block(x, y), bytes(data)):
        fw_map.add(packet)
    assert fw_map.blocks == 1 and fw_map.cells[x, y] == -100 and np.count_nonzero(fw_map.cells) == 1
    assert fw_map.box == (768, 992, 800, 1008)


def test_parts_out_of_order_or_of_another_block_are_dropped():
    fw_map = FirmwareMap()
    first, second = parts(5, b"\x01" * 512), parts(6, b"\x02" * 512)
    for packet in [first[0], first[1], second[2], first[3], *second]:
        fw_map.add(packet)
    assert fw_map.blocks == 1 and fw_map.dropped == 2  # block 5 broken off; block 6 whole
    assert (fw_map.cells[block_origin(6)[0], block_origin(6)[1]]) == 2 and not fw_map.cells[block_origin(5)].any()


def test_a_block_beyond_the_map_or_a_short_part_is_dropped():
    """Block addresses stop at 1536 x 1536 / 512 = 4608; a part is 128 bytes."""
    fw_map = FirmwareMap()
    for packet in parts(4608, bytes(512)):
        fw_map.add(packet)
    fw_map.add(Packet("Q", "D", 1, 0, payload=b"\x01" * 100))
    assert fw_map.blocks == 0 and fw_map.dropped == 2 and fw_map.box is None and not fw_map.cells.any()


def test_the_image_colours_obstacles_and_floor_clear_where_unknown_and_is_a_valid_png():
    fw_map = FirmwareMap()
    values = np.zeros((32, 16), dtype=np.int8)
    values[3, 4], values[5, 6], values[7, 8] = 100, -100, -10
    for packet in parts(0, values.tobytes()):
        fw_map.add(packet)
    image = fw_map.image()
    assert image.shape == (16, 32, 4)  # rows along y, columns along x
    assert tuple(image[4, 3]) == (40, 150, 255, 210) and tuple(image[6, 5]) == (220, 40, 40, 210) and image[0, 0, 3] == 0
    assert image[8, 7, 3] == 75  # less sure, more clear: 60 + 1.5 |value|
    data = rgba_png(image)
    width, height, depth, colour = struct.unpack(">IIBB", data[16:26])
    import pygame  # (reads it back as a viewer would)

    read = pygame.image.load(io.BytesIO(data), "map.png")
    pixels = np.frombuffer(pygame.image.tobytes(read, "RGBA"), dtype=np.uint8).reshape(16, 32, 4)
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and (width, height, depth, colour) == (32, 16, 8, 6) and np.array_equal(pixels, image)


def test_the_image_lies_in_the_firmware_frame_of_the_start_pose():
    """Cell c spans c * 8 mm - 6.144 m onwards along the firmware's x (its start heading) and y."""
    fw_map = FirmwareMap()
    for packet in parts(firmware_block(800, 768), bytes(512)):
        fw_map.add(packet)
    start = (1.0, 2.0, math.radians(90))
    corner, matrix = fw_map.placement(start)
    fx, fy = fw_map.box[0] * CELL_M - 6.144, fw_map.box[1] * CELL_M - 6.144  # 0.256 m ahead, 0 left
    assert np.allclose(corner[:2], (1.0 - fy, 2.0 + fx), atol=1e-12)
    assert np.allclose(np.array(matrix)[:2, :2] @ (1.0, 0.0), (0.0, CELL_M), atol=1e-15)  # a column step: along the heading


def test_the_window_over_a_world_covers_it_in_the_firmware_frame():
    """A 2 x 1 m world, the robot started at its centre facing +y: the firmware's x runs along
    world y, so the window is 1 m (125 cells) along x and 2 m (250 cells) along y, centred."""
    x0, y0, x1, y1 = window((0.0, 0.0, 2.0, 1.0), (1.0, 0.5, math.pi / 2))
    assert (x1 - x0, y1 - y0) in ((125, 250), (126, 251), (125, 251), (126, 250))  # whole cells around rounding
    assert abs((x0 + x1) / 2 - CELLS / 2) <= 1 and abs((y0 + y1) / 2 - CELLS / 2) <= 1
