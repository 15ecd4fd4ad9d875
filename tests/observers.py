"""Run observers for tests: the run loop keeps only the current readings (bounded memory), so a
test that looks at every step's readings collects them itself; a stand-in for a live viewer."""

from __future__ import annotations


class KeepReadings:
    """Collects every sample's readings of robot `index` in `self.readings`."""

    def __init__(self, index: int = 0):
        self.index = index
        self.readings: list = []

    def on_sample(self, world, logs) -> None:  # noqa: ANN001
        self.readings.append(logs[self.index].latest)


class FakeLive:
    """Stands in for the live stream (a viewer): records which entities reach it."""

    def __init__(self):
        self.paths: set[str] = set()
        self.events: list[str] = []

    def recorder(self, path):  # noqa: ANN001
        """A Recorder writing `path` whose live stream is this stand-in."""
        from sim.views.recording.recorder import Recorder

        live = self

        class LiveRecorder(Recorder):
            def _open_live(self, rr, blueprint):  # noqa: ANN001
                self._live = live
                self.streams.append(live)

        return LiveRecorder(path, live=True)

    def log(self, path, data, static=False):  # noqa: ANN001
        self.paths.add("/" + path)
        if path == "events":
            self.events.append(str(data.as_component_batches()[0].as_arrow_array()[0]))

    def send_columns(self, path, times, columns):  # noqa: ANN001
        self.paths.add("/" + path)

    def set_time(self, *args, **kwargs):  # noqa: ANN002, ANN003
        pass

    def flush(self, **kwargs):  # noqa: ANN003
        pass

    def disconnect(self):
        pass
