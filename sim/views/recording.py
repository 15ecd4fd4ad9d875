"""Record a run to a rerun `.rrd` file (and optionally live to a viewer): an observer of `sim.run.run`.

Layout (all on the timeline "sim_time", seconds of simulated time):

    world                         Transform3D scale (1, -1, 1): y up in rerun's y-down 2D view
    world/map/{walls,floor,lines,holes,goals,lights,starts}   static, drawn once
    world/<robot>/body            Points2D, the body circle at the true pose
    world/<robot>/heading         Arrows2D from the centre along the true heading
    world/<robot>/rays, hits      IR rays (LineStrips2D) to the distance each sensor reports, and
                                  that point (Points2D) when it reports one (0.1-0.8 m)
    world/<robot>/trail/truth     one 2-point segment per sample; the blueprint shows all history
    world/<robot>/trail/<est>     same for each odometry estimate
    world/<robot>/ghost/<est>     Points2D, where the estimate believes the robot is
    errors/<robot>/position/<est> Scalars, |estimate - truth| (m)
    errors/<robot>/heading/<est>  Scalars, wrapped heading error (rad)
    sensors/<robot>/<sensor>      Scalars, raw readings (one series per channel)

Per-sample values go into numpy buffers and leave in chunks with `send_columns` (DESIGN.md §6):
per-step `log` calls would cost more than the simulation. On the end of a run, whatever the
reason (goal, error, Ctrl-C), the buffers are flushed and the file closed, so it stays readable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sim.kinematics import wrap_angle
from sim.views.chassis_view import ChassisLayer
from sim.world import IR_RAY_LENGTH, World

if TYPE_CHECKING:
    from sim.run import RobotLog, RunResult

TIMELINE = "sim_time"
CHUNK = 1000
"""Samples per `send_columns` batch."""

SENSORS = ("encoder_ticks", "mouse_counts", "ir_raw", "line", "border", "light")
"""Readings fields recorded as time series, in buffer column order."""

ESTIMATE_COLOURS = ((230, 120, 20), (40, 110, 220), (170, 60, 190), (20, 160, 150), (200, 40, 60))
TRUTH_COLOUR = (30, 170, 60)


def _colour(rgb: tuple[float, float, float]) -> tuple[int, int, int]:
    return tuple(int(round(255 * c)) for c in rgb)


def _closed(vertices) -> np.ndarray:
    v = np.asarray(vertices, dtype=np.float64)
    return np.vstack((v, v[:1]))


@dataclass
class _Track:
    """Per-robot buffers of one chunk of samples."""

    name: str
    estimates: list[str]
    ir: np.ndarray  # (k, 3) body-frame (x, y, direction) of each IR sensor
    body_radius: float
    widths: list[int]
    time: np.ndarray = field(init=False)
    poses: np.ndarray = field(init=False)  # (n, 1 + len(estimates), 3): truth first
    sensors: np.ndarray = field(init=False)
    ray: np.ndarray = field(init=False)  # (n, k) IR distances as the sensors report them
    last: np.ndarray | None = None  # the previous chunk's last poses, for continuous trails
    count: int = 0

    def __post_init__(self) -> None:
        self.time = np.empty(CHUNK)
        self.poses = np.empty((CHUNK, 1 + len(self.estimates), 3))
        self.sensors = np.empty((CHUNK, sum(self.widths)))
        self.ray = np.empty((CHUNK, len(self.ir)))


class Recorder:
    """Run observer that writes a rerun recording to `path` (None: none) and, with `live`, streams
    it to a viewer it spawns. Use as `observers=[Recorder(path)]`."""

    def __init__(self, path: str | Path | None, live: bool = False, application_id: str = "ctsim"):
        self.path = Path(path) if path is not None else None
        self.live = live
        self.application_id = application_id
        self.rec: Any = None
        self._tracks: list[_Track] = []
        self._chassis: ChassisLayer | None = None

    # --- observer interface ---------------------------------------------------------------

    def on_start(self, world: World, logs: list[RobotLog]) -> None:
        """Open the recording, send the blueprint and draw the world once."""
        import rerun as rr

        self.rec = rr.RecordingStream(self.application_id, send_properties=False)
        blueprint = self.blueprint([log.name for log in logs])
        sinks = []
        if self.path is not None:
            sinks.append(rr.FileSink(str(self.path)))
        if self.live:
            self.rec.spawn(connect=False)
            sinks.append(rr.GrpcSink())
        self.rec.set_sinks(*sinks, default_blueprint=blueprint)
        self.rec.log("world", rr.Transform3D(scale=(1.0, -1.0, 1.0)), static=True)
        log_world(self.rec, world.spec)
        self._tracks = []
        self._chassis = ChassisLayer.for_world(self.rec, world, TIMELINE)

    def on_sample(self, world: World, logs: list[RobotLog]) -> None:
        """Copy this sample's truth, estimates and readings into the buffers. Rays are drawn from
        the readings' distances, not cast again: a second ray cast per sensor would cost more
        than all the rest of the recording."""
        if not self._tracks:
            self._tracks = [self._track(log) for log in logs]
            self._style()
        for log, track in zip(logs, self._tracks):
            n = track.count
            track.time[n] = world.time
            track.poses[n, 0] = log.truth_array()[-1]
            for k, poses in enumerate(log.estimate_arrays().values(), 1):
                track.poses[n, k] = poses[-1]
            readings = log.latest
            track.sensors[n] = np.concatenate([getattr(readings, f) for f in SENSORS])
            track.ray[n] = readings.ir_distance
            track.count = n + 1
            if track.count == CHUNK:
                self._send(track)
        if self._chassis is not None:
            self._chassis.on_sample(world, logs)

    def on_end(self, result: RunResult) -> None:
        """Flush what is buffered and close the file (also after an error or Ctrl-C)."""
        self.close()

    def close(self) -> None:
        """Send the buffered samples and finish the recording; safe to call twice."""
        if self.rec is None:
            return
        try:
            for track in self._tracks:
                if track.count:
                    self._send(track)
            self.rec.flush()
        finally:
            self.rec.disconnect()
            self.rec = None

    # --- internals ------------------------------------------------------------------------

    def _track(self, log: RobotLog) -> _Track:
        spec = log.spec
        first = log.latest
        return _Track(
            name=log.name,
            estimates=list(log.estimate_arrays()),
            ir=np.array([(*s.position, s.direction) for s in spec.ir]).reshape(-1, 3),
            body_radius=spec.body_radius,
            widths=[len(getattr(first, f)) for f in SENSORS],
        )

    def _style(self) -> None:
        """Static colours of each robot's trails and ghosts (the data itself is temporal)."""
        import rerun as rr

        for track in self._tracks:
            base = f"world/{track.name}"
            self.rec.log(f"{base}/trail/truth", rr.LineStrips2D.from_fields(colors=TRUTH_COLOUR, radii=0.003), static=True)
            self.rec.log(f"{base}/body", rr.Points2D.from_fields(colors=(*TRUTH_COLOUR, 90)), static=True)
            for label, colour in zip(track.estimates, ESTIMATE_COLOURS):
                self.rec.log(f"{base}/trail/{label}", rr.LineStrips2D.from_fields(colors=colour, radii=0.002), static=True)
                self.rec.log(f"{base}/ghost/{label}", rr.Points2D.from_fields(colors=colour, radii=0.01), static=True)

    def _send(self, track: _Track) -> None:
        """Send one chunk of a robot's samples as columns."""
        import rerun as rr

        n = track.count
        rec, base = self.rec, f"world/{track.name}"
        times = [rr.TimeColumn(TIMELINE, duration=track.time[:n].copy())]
        poses = track.poses[:n]
        truth = poses[:, 0]
        ones = [1] * n

        rec.send_columns(f"{base}/body", times, rr.Points2D.columns(positions=truth[:, :2], radii=np.full(n, track.body_radius)).partition(ones))
        heading = track.body_radius * np.column_stack((np.cos(truth[:, 2]), np.sin(truth[:, 2])))
        rec.send_columns(f"{base}/heading", times, rr.Arrows2D.columns(origins=truth[:, :2], vectors=heading).partition(ones))

        previous = track.last if track.last is not None else poses[0]
        starts = np.concatenate((previous[None], poses[:-1]))
        for k, label in enumerate(["truth", *track.estimates]):
            segments = np.stack((starts[:, k, :2], poses[:, k, :2]), axis=1)
            rec.send_columns(f"{base}/trail/{label}", times, rr.LineStrips2D.columns(strips=segments).partition(ones))
            if k:
                rec.send_columns(f"{base}/ghost/{label}", times, rr.Points2D.columns(positions=poses[:, k, :2]).partition(ones))
                error = poses[:, k] - truth
                rec.send_columns(f"errors/{track.name}/position/{label}", times, rr.Scalars.columns(scalars=np.hypot(error[:, 0], error[:, 1])))
                rec.send_columns(f"errors/{track.name}/heading/{label}", times, rr.Scalars.columns(scalars=wrap_angle(error[:, 2])))
        track.last = poses[-1].copy()

        if len(track.ir):
            self._send_rays(track, times, truth)
        column = 0
        for name, width in zip(SENSORS, track.widths):
            if width:
                values = track.sensors[:n, column : column + width].ravel()
                rec.send_columns(f"sensors/{track.name}/{name}", times, rr.Scalars.columns(scalars=values).partition([width] * n))
            column += width
        track.count = 0

    def _send_rays(self, track: _Track, times: list, truth: np.ndarray) -> None:
        import rerun as rr

        n, k = len(truth), len(track.ir)
        c, s = np.cos(truth[:, 2])[:, None], np.sin(truth[:, 2])[:, None]
        x, y, direction = track.ir.T
        origin = np.stack((truth[:, :1] + c * x - s * y, truth[:, 1:2] + s * x + c * y), axis=-1)
        distance = track.ray[:n]
        hit = np.isfinite(distance)
        reach = np.where(hit, distance, IR_RAY_LENGTH)[..., None]
        angle = truth[:, 2:3] + direction
        end = origin + reach * np.stack((np.cos(angle), np.sin(angle)), axis=-1)
        rays = np.stack((origin, end), axis=2).reshape(n * k, 2, 2)
        self.rec.send_columns(f"world/{track.name}/rays", times, rr.LineStrips2D.columns(strips=rays).partition([k] * n))
        self.rec.send_columns(f"world/{track.name}/hits", times, rr.Points2D.columns(positions=end[hit]).partition(hit.sum(axis=1)))

    @staticmethod
    def blueprint(robots: list[str]) -> Any:
        """The map (with full trails) beside the error plots, sensors below them."""
        import rerun.blueprint as rrb

        history = rrb.VisibleTimeRanges(
            [rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative())]
        )
        trails = {f"/world/{name}/trail": history for name in robots}
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial2DView(origin="/world", name="map", overrides=trails),
                rrb.Vertical(
                    rrb.TimeSeriesView(origin="/errors", contents="$origin/*/position/**", name="position error (m)"),
                    rrb.TimeSeriesView(origin="/errors", contents="$origin/*/heading/**", name="heading error (rad)"),
                    rrb.TimeSeriesView(origin="/sensors", name="sensors (raw)"),
                ),
                column_shares=[3, 2],
            ),
            rrb.TimePanel(timeline=TIMELINE),
            collapse_panels=True,
        )


def log_world(rec: Any, spec) -> None:
    """Draw a WorldSpec once, as static data under world/map."""
    import rerun as rr

    def strips(path: str, shapes, colour, radius: float = 0.002) -> None:
        if shapes:
            rec.log(path, rr.LineStrips2D([_closed(v) for v in shapes], colors=colour, radii=radius), static=True)

    xmin, ymin, xmax, ymax = spec.bounds
    strips("world/map/bounds", [((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax))], (120, 120, 120), 0.001)
    for i, region in enumerate(spec.floor):
        strips(f"world/map/floor/{i}", [region.vertices], _colour(region.colour), 0.003)
    strips("world/map/walls", [w.vertices for w in spec.walls], (200, 200, 200), 0.004)
    strips("world/map/holes", [h.vertices for h in spec.holes], (10, 10, 10), 0.006)
    strips("world/map/goals", [g.vertices for g in spec.goals], (60, 220, 90), 0.004)
    if spec.lines:
        rec.log(
            "world/map/lines",
            rr.LineStrips2D([np.asarray(line.points) for line in spec.lines], radii=[line.width / 2 for line in spec.lines], colors=[_colour(line.colour) for line in spec.lines]),
            static=True,
        )
    if spec.lights:
        rec.log("world/map/lights", rr.Points2D([light.position for light in spec.lights], radii=0.03, colors=(255, 220, 40)), static=True)
    if spec.starts:
        origins = [(s.x, s.y) for s in spec.starts]
        vectors = [(0.1 * math.cos(s.heading), 0.1 * math.sin(s.heading)) for s in spec.starts]
        rec.log("world/map/starts", rr.Arrows2D(origins=origins, vectors=vectors, colors=(90, 160, 255)), static=True)
