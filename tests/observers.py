"""Run observers for tests: the run loop keeps only the current readings (bounded memory), so a
test that looks at every step's readings collects them itself."""

from __future__ import annotations


class KeepReadings:
    """Collects every sample's readings of robot `index` in `self.readings`."""

    def __init__(self, index: int = 0):
        self.index = index
        self.readings: list = []

    def on_sample(self, world, logs) -> None:  # noqa: ANN001
        self.readings.append(logs[self.index].latest)
