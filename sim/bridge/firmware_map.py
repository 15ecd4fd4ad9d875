"""The firmware's own occupancy map, put together from its MAP packets as c't-Sim's map window
shows it, and drawn as an image in the world's frame.

The PC firmware keeps a 12.288 m square map of 8 mm cells (125 per metre) centred on its start
pose, x along its start heading, y to the left; a cell holds an int8, negative for an obstacle,
positive for driven-over floor, 0 unknown. Its map thread sends changed 512-byte blocks as four
128-byte packets Q/D, Q/E, Q/F, Q/G, all with the block's address in data_l (ctbot-protocol.md §5).
A block is two 16 x 16 sections side by side along x, each stored x-major; blocks fill 512-cell
macroblocks row by row, 16 blocks (512 cells) to a row and 32 rows of 16 cells; macroblocks fill
the map three to a row (the firmware's `get_block` in map.c, inverted here).
"""

from __future__ import annotations

import math

import numpy as np

from sim.bridge import protocol as p

CELLS = 1536
"""Cells along each side of the firmware's map (12.288 m at 125 per metre)."""
CELL_M = 0.008
HALF_M = CELLS * CELL_M / 2
"""The map's centre, the firmware's start pose, from its corner (m)."""
SECTION, MACROBLOCK, MACROBLOCKS_PER_ROW = 16, 512, 3
BLOCK_BYTES, PART_BYTES = 512, 128
BLOCKS = CELLS * CELLS // BLOCK_BYTES
PARTS = (p.MAP_POS_X, p.MAP_POS_Y, p.MAP_HEADING, p.MAP_LAST_PART)
"""The four parts of a block, in the order the firmware sends them (the first three also carry
its pose: x and y cells, heading in degrees)."""
OBSTACLE, FREE = (220, 40, 40), (40, 150, 255)
MIN_ALPHA, MAX_ALPHA = 60, 230
"""Opacity (of 255) of the cells the firmware knows least and best: the world shows through."""


def block_origin(block: int) -> tuple[int, int]:
    """The map cell (x, y) of a block's first byte."""
    macro, local = divmod(block, MACROBLOCK)
    return (macro % MACROBLOCKS_PER_ROW) * MACROBLOCK + (local % SECTION) * 2 * SECTION, (macro // MACROBLOCKS_PER_ROW) * MACROBLOCK + (local // SECTION) * SECTION


class FirmwareMap:
    """The cells received so far (`cells[x, y]`, int8), the box of cells they cover and a count
    of complete blocks (`blocks`; the image is redrawn when it changed). A block whose parts come
    out of order or with different addresses is dropped, as c't-Sim drops it."""

    def __init__(self) -> None:
        self.cells = np.zeros((CELLS, CELLS), dtype=np.int8)
        self.box: tuple[int, int, int, int] | None = None
        """Cells x0, y0, x1, y1 (exclusive) of every block received."""
        self.blocks = 0
        self.dropped = 0
        self._block = -1
        self._parts: list[bytes] = []

    def add(self, packet: p.Packet) -> None:
        """One Q packet (others and the drawing sub-commands are ignored)."""
        if packet.sub not in PARTS:
            return
        index = PARTS.index(packet.sub)
        if index != len(self._parts) or (index and packet.data_l != self._block) or len(packet.payload) != PART_BYTES:
            self.dropped += 1
            self._parts = []
            if index:
                return
        if index == 0:
            self._block, self._parts = packet.data_l & 0xFFFF, []
        self._parts.append(packet.payload)
        if len(self._parts) == len(PARTS):
            self._store(self._block, b"".join(self._parts))
            self._parts = []

    def _store(self, block: int, data: bytes) -> None:
        if block >= BLOCKS:
            self.dropped += 1
            return
        x, y = block_origin(block)
        self.cells[x : x + 2 * SECTION, y : y + SECTION] = np.frombuffer(data, dtype=np.int8).reshape(2 * SECTION, SECTION)
        box = (x, y, x + 2 * SECTION, y + SECTION)
        self.box = box if self.box is None else (min(self.box[0], x), min(self.box[1], y), max(self.box[2], box[2]), max(self.box[3], box[3]))
        self.blocks += 1

    def image(self, window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """The cells of `window` (x0, y0, x1, y1; default the box received so far) as RGBA, rows
        along the firmware's y, columns along x: obstacles red, driven floor blue, the more
        opaque the surer the firmware is (|value| up to 128), unknown cells clear. (c't-Sim's
        map window shows the same values in grey, which vanishes on ctsim's grey floor.)"""
        x0, y0, x1, y1 = window or self.box or (0, 0, 0, 0)
        values = self.cells[x0:x1, y0:y1].T.astype(np.int16)
        out = np.empty(values.shape + (4,), dtype=np.uint8)
        out[..., :3] = np.where((values < 0)[..., None], OBSTACLE, FREE)
        out[..., 3] = np.where(values == 0, 0, np.minimum(MIN_ALPHA + np.abs(values) * 3 // 2, MAX_ALPHA))
        return out

    def placement(self, start: tuple[float, float, float], window: tuple[int, int, int, int] | None = None) -> tuple[tuple[float, float, float], list[list[float]]]:
        """Where the image of `window` lies in the world for a robot that started at `start` (x, y
        m, heading rad): the world position of its corner and the 3 x 3 matrix from pixels to
        metres (the firmware's frame is the start pose; cell c spans c * 8 mm - 6.144 m onwards)."""
        x0, y0, _, _ = window or self.box or (0, 0, 0, 0)
        fx, fy = x0 * CELL_M - HALF_M, y0 * CELL_M - HALF_M
        c, s = math.cos(start[2]), math.sin(start[2])
        corner = (start[0] + c * fx - s * fy, start[1] + s * fx + c * fy, 0.0)
        return corner, [[c * CELL_M, -s * CELL_M, 0.0], [s * CELL_M, c * CELL_M, 0.0], [0.0, 0.0, 1.0]]


def window(bounds: tuple[float, float, float, float], start: tuple[float, float, float]) -> tuple[int, int, int, int]:
    """The map cells (x0, y0, x1, y1) that cover a world's `bounds` for a robot that started at
    `start`: one fixed image size for a whole run (rerun refuses a PNG stream that changes size)."""
    c, s = math.cos(start[2]), math.sin(start[2])
    corners = [(x - start[0], y - start[1]) for x in bounds[0::2] for y in bounds[1::2]]
    local = np.array([(c * dx + s * dy, -s * dx + c * dy) for dx, dy in corners])
    low = np.clip(np.floor((local.min(axis=0) + HALF_M) / CELL_M).astype(int), 0, CELLS)
    high = np.clip(np.ceil((local.max(axis=0) + HALF_M) / CELL_M).astype(int), 0, CELLS)
    return int(low[0]), int(low[1]), int(max(high[0], low[0] + 1)), int(max(high[1], low[1] + 1))

