"""Standard normals drawn a block at a time from each sensor's own generator.

A Python call into a numpy generator per sensor and step costs more than the sensor's physics.
`numpy.random.Generator.standard_normal(size=m)` gives the same numbers as m single draws, so
drawing ahead in blocks and handing them out in order keeps every sensor's noise sequence (and the
per-sensor seeding) exactly as drawing one at a time: runs stay bit-identical across processes.
"""

from __future__ import annotations

import numpy as np

BLOCK = 1024
"""Normals drawn ahead per generator..."""
HELD = 1 << 17
"""...unless that would hold more than this many (1 MB) for all of them: a crowd of noisy robots
draws shorter blocks (at least MIN_BLOCK) rather than tens of megabytes."""
MIN_BLOCK = 16


class NormalBlocks:
    """Rows of standard normals, one row per generator: row k's values from `used[k]` on are its
    generator's next ones. Consumers take from a row and advance `used` (compiled kernels too);
    `reserve(count)` before each step that takes at most `count` from any row."""

    def __init__(self, rngs: list[np.random.Generator], block: int | None = None):
        self.rngs = rngs
        if block is None:
            block = max(MIN_BLOCK, min(BLOCK, HELD // max(len(rngs), 1)))
        self.values = np.zeros((len(rngs), block))
        self.used = np.full(len(rngs), block, dtype=np.int64)
        self._left = 0
        """Values every row still holds (a lower bound), so that most steps check nothing."""

    def reserve(self, count: int) -> None:
        """Make sure every row holds at least `count` unused values (refilling from its generator)."""
        if self._left < count:
            block = self.values.shape[1]
            for k, rng in enumerate(self.rngs):
                start = int(self.used[k])
                if block - start < max(count, block // 2):
                    kept = block - start
                    self.values[k, :kept] = self.values[k, start:]
                    self.values[k, kept:] = rng.standard_normal(block - kept)
                    self.used[k] = 0
            self._left = block - int(self.used.max()) if len(self.rngs) else block
        self._left -= count

    def restart(self, row: int, rng: np.random.Generator) -> None:
        """Row `row` draws from `rng` from now on: the values it still holds are replaced by
        `rng`'s first ones, so that every row stays where `take` expects it."""
        self.rngs[row] = rng
        start = int(self.used[row])
        self.values[row, start:] = rng.standard_normal(self.values.shape[1] - start)

    def take(self, count: int) -> np.ndarray:
        """The next `count` normals of every row (rows, count), for consumers that take the same
        number from every row each step (so all rows are used alike)."""
        self.reserve(count)
        start = int(self.used[0]) if len(self.rngs) else 0
        self.used += count
        return self.values[:, start : start + count]
