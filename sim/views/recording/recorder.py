"""Record a run to a rerun `.rrd` file (and live to a viewer): an observer of `sim.run.loop.run`.

Layout (all on the timeline "sim_time", seconds of simulated time):

    world                              Transform3D scale (1, -1, 1): y up in rerun's y-down 2D view
    world/map/floor                    the map as an image (drawn like the PNG figures), static
    world/map/starts                   start poses (arrows), static
    world/map/key/lines, edges, labels the colour key right of the map, a rimmed swatch over each
                                       name: truth, each estimate, the error plots' 3σ bands
                                       (whose legends are hidden), static
    world/<robot>/body                 Transform3D: the true pose; body/outline is static in it
                                       (a chassis's polygon, else a circle), so is body/name, the
                                       robot's name where several share a run; body/wheels of a
                                       general chassis: Arrows2D, as the steering turns
    world/<robot>/chassis/icr          Points2D: the ICR of a general chassis's motion, in view
    world/<robot>/estimate/<est>       Transform3D: the estimated pose; estimate/<est>/outline static
    world/<robot>/rays, hits           IR rays to the distance each sensor reports, and that point
    world/<robot>/trail/<label>        LineStrips2D, one piece per TRAIL_EVERY samples (truth and
                                       each estimate), the truth's split where the robot was put
                                       down (`RobotLog.puts`); the blueprint shows all history
    world/<robot>/ellipse/<est>        LineStrips2D, the 95 % ellipse of the estimate's position
                                       every ELLIPSE_EVERY samples (those with a covariance); the
                                       blueprint shows the last ELLIPSE_RECENT_S seconds
    errors/<robot>/position            Scalars, |estimate - truth| (mm), one series per estimate (the
                                       first wide beneath the others: `layout.error_widths`)
    errors/<robot>/position/band       Scalars, 3 sigma of the position error's major axis (mm)
    errors/<robot>/heading             Scalars, wrapped heading error (deg), one series per estimate
    errors/<robot>/heading/band_upper  Scalars, +3 sigma of the heading (deg); band_lower -3 sigma
    sensors/<group>/<robot>/<field>    Scalars, readings in their units (SENSOR_GROUPS)
    events                             TextLog: start, collisions, wheel faults, falls, goal,
                                       notes (the first of each kind), messages, end, errors
    facts                              TextDocument: world, robots, controllers, seed, dt, version

Per-sample values go into numpy buffers and leave in chunks with `send_columns` (DESIGN.md §6):
per-step `log` calls would cost more than the simulation. On the end of a run, whatever the
reason (goal, error, Ctrl-C), the buffers are flushed and the file closed, so it stays readable.
The live view is a second stream beside the file's: a viewer that is missing or goes away costs
the live view only, with one line on stderr.
"""

from __future__ import annotations

import logging
import operator
import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bots.sensor_kinds import BY_FIELD, KINDS
from sim.kinematics import wrap_angle
from sim.out_files import trouble
from sim.views import palette
from sim.views.chassis_view import ChassisLayer, body_outline, fault_text
from sim.views.particles import ParticleLayer, localisers
from sim.views.recording.arrow import ArrowOwned, lazy_rerun, strips, turn, xyz
from sim.views.recording.layout import (
    BAND_LABEL,
    ELLIPSE_EVERY,
    ELLIPSE_POINTS,
    FIELDS,
    SCALE,
    SENSOR_GROUPS,
    TIMELINE,
    TRAIL_EVERY,
    blueprint,
    ellipses,
    error_widths,
    field_channels,
    light_labels,
    log_key,
    log_world,
    rgb,
)
from sim.views.recording.live import LiveStream
from sim.world import IR_RAY_LENGTH, World

RAYS = next(kind for kind in KINDS if kind.rays)
"""The kind drawn as rays from its sensors (the IR sensors' distances)."""

if TYPE_CHECKING:
    from sim.run.samples import RobotLog, RunResult

FLUSH_WAIT_S = 300.0
"""Longest wait (s) for rerun to write out what a run sent it: its flush, told of a file writer
that died, sometimes waits for ever."""
STALL_S = 10.0
"""Longest wait (s) for the end of a recording (rerun's flush and close) while its file does not
grow and its disk is full or its file-size limit reached (`trouble`): once its file writer died
so, the close waited for ever in half of the tries (in every one of `ctsim run`'s)."""
FOOTER = b"RRF2FOOT"
"""What ends a whole .rrd file of this rerun (its footer's mark, some bytes before the end)."""
CHUNK = 8000
"""Samples per `send_columns` batch. Each batch costs rerun's conversions once per entity (8,000
samples cost a recorded run a quarter less than 4,000), and rerun keeps some 400 bytes per chunk
sent until the file is closed (its footer): fewer, longer chunks are cheaper and keep a long run's
memory flat."""


@dataclass
class _Track:
    """One robot's part of the recording: what is sent of it so far, and the events noted. Poses
    and readings come from its RobotLog's columns when a chunk is sent; only a general chassis's
    readings, whose per-wheel fields are not among the run's columns, are buffered sample by sample."""

    log: RobotLog
    estimates: list[str]
    ir: np.ndarray  # (k, 3) body-frame (x, y, direction) of each IR sensor
    channels: list[tuple[str, ...]]  # per FIELDS, the names of its recorded channels (the spec's)
    picks: list[np.ndarray | None]  # per FIELDS, which entries of the readings field (None: all)
    buffered: bool = False  # a general chassis: readings kept per sample in `sensors`
    sensors: np.ndarray = field(init=False)
    start: int = 0  # index of the first sample not sent yet
    count: int = 0  # samples in `sensors` (buffered only)
    tail: np.ndarray | None = None  # the last trail point of each label, (1 + estimates, 2)
    collisions: int = 0
    failures: int = 0
    notes: int = 0  # kinds of the RobotLog's notes already in the events
    fell: bool = False
    goal: bool = False

    def __post_init__(self) -> None:
        recorded = [(f, pick) for f, channels, pick in zip(FIELDS, self.channels, self.picks) if channels]
        self._fields = operator.attrgetter(*(f for f, _ in recorded), "time")  # (two or more names: a tuple)
        self._picks = [pick for _, pick in recorded]
        self.sensors = np.empty((CHUNK if self.buffered else 0, sum(map(len, self.channels))))

    def keep(self, readings: Any) -> None:
        """Buffer one sample's recorded channels (a general chassis only)."""
        *parts, _ = self._fields(readings)
        parts = [part if pick is None else part[pick] for part, pick in zip(parts, self._picks)]
        np.concatenate(parts, out=self.sensors[self.count])
        self.count += 1

    def columns(self, stop: int) -> dict[str, np.ndarray]:
        """The recorded readings fields of samples [start, stop): name -> (n, width)."""
        n = stop - self.start
        if self.buffered:
            widths = np.cumsum([0, *map(len, self.channels)])
            return {f: self.sensors[:n, widths[k] : widths[k + 1]] for k, f in enumerate(FIELDS) if self.channels[k]}
        values = self.log.readings(slice(self.start, stop))
        return {f: values[f] if pick is None else values[f][:, pick] for f, channels, pick in zip(FIELDS, self.channels, self.picks) if channels}


class Recorder(LiveStream):
    """Run observer that writes a rerun recording to `path` (None: none) and, with `live`, also
    streams it to a viewer: the one at `connect` (a rerun+http:// URL) or else one it spawns.
    `facts` are extra lines for the run's facts document (option -> value). `colours` (robot name
    -> RGB) draws those robots' outlines and true trails in their own colour, with their name on
    the map (a contest's two bots), instead of truth's green.
    Use as `observers=[Recorder(path)]`."""

    def __init__(self, path: str | Path | None, live: bool = False, connect: str | None = None, application_id: str = "ctsim",
                 facts: dict[str, Any] | None = None, colours: dict[str, palette.RGB] | None = None):  # fmt: skip
        self.path = Path(path) if path is not None else None
        self.colours = dict(colours or {})
        self.live = live or connect is not None
        self.connect = connect
        self.application_id = application_id
        self.facts = dict(facts or {})
        self.streams: list[Any] = []
        self.live_lost: str | None = None
        self.write_error: str | None = None
        """Why the recording file is incomplete (its writer failed: disk full, I/O error), if it is."""
        self._live: Any = None
        self._live_due = 0.0  # time.monotonic() of the next live send
        self._tracks: list[_Track] = []
        self._sent = 0  # samples sent so far (of every robot)
        self._chassis: ChassisLayer | None = None
        self._particles: ParticleLayer | None = None
        self._messages: _Messages | None = None
        self._now = 0.0

    # --- observer interface ---------------------------------------------------------------

    def on_start(self, world: World, logs: list[RobotLog]) -> None:
        """Open the recording (and the live view), send the blueprint, draw the world once; an
        interrupt meanwhile still closes what was opened."""
        try:
            self._open(world, logs)
        except BaseException:
            self.close()
            raise

    def _open(self, world: World, logs: list[RobotLog]) -> None:
        rr = lazy_rerun()
        groups = [g for g, (_, fields) in SENSOR_GROUPS.items() if any(field_channels(log.spec, f)[0] for log in logs for f in fields)]
        self._tracks = [self._track(log) for log in logs]
        self.colours = self.colours or palette.robot_colours([log.name for log in logs])
        key = self._key()
        views = blueprint(world.spec, {log.name: log.estimate_names for log in logs}, groups, [log.name for log in logs if localisers(log.estimators)],
                          [label for label, _, _ in key])  # fmt: skip
        self.streams = []
        if self.path is not None:
            rec = rr.RecordingStream(self.application_id, send_properties=False)
            rec.set_sinks(rr.FileSink(str(self.path)), default_blueprint=views)
            self.streams.append(rec)
        if self.live:
            self._open_live(rr, views)
        self._log("world", rr.Transform3D(scale=(1.0, -1.0, 1.0)), static=True)
        log_world(self._log, world.spec)
        self._log("facts", rr.TextDocument(self._facts_text(world, logs), media_type=rr.MediaType.MARKDOWN), static=True)
        self._chassis = ChassisLayer.for_world(self._log, self._columns, world, TIMELINE)
        self._particles = ParticleLayer.for_run(self._columns, self._event, logs, TIMELINE)
        self._style()
        log_key(self._log, world.spec, key)
        if self._chassis is not None:
            self._chassis.style({i: log.name for i, log in enumerate(logs)})
        self._now = world.time
        names = ", ".join(f"{log.name} ({log.controller_name})" for log in logs)
        self._event(f"start: {names} in {world.spec.name}", "INFO")
        self._messages = _Messages(self)
        logging.getLogger().addHandler(self._messages)

    def on_sample(self, world: World, logs: list[RobotLog]) -> None:
        """Note this sample's events; every CHUNK samples (and at the live view's pace) send what
        the run's columns hold since the last send. Rays are drawn from the readings' distances,
        not cast again: a second ray cast per sensor would cost more than all the rest of the
        recording."""
        self._now = world.time
        for robot, log, track in zip(world.robots, logs, self._tracks):
            if track.buffered:
                track.keep(log.latest)
            if (robot.collisions != track.collisions or robot.fallen != track.fell or len(log.notes) != track.notes
                    or (log.goal_time is not None) != track.goal or track.buffered):  # fmt: skip
                self._note_events(robot, log, track)
        if self._chassis is not None:
            self._chassis.on_sample(world, logs)
        if self._particles is not None:
            self._particles.on_sample(world, logs)
        count = len(logs[0]) if logs else 0
        if count - self._sent >= CHUNK or (self._live is not None and (self._sent == 0 or time.monotonic() >= self._live_due)):
            self._send_all(count)
            if self._live is not None:
                self._check_live()

    def _note_events(self, robot: Any, log: RobotLog, track: _Track) -> None:
        """Events of one robot since the last sample: collisions, wheel faults, notes, a fall, the goal."""
        if robot.collisions != track.collisions:
            track.collisions = robot.collisions
            self._event(f"{log.name}: collision {robot.collisions} at ({robot.pose[0]:.3f}, {robot.pose[1]:.3f}) m", "WARN")
        if track.buffered:
            failures = log.latest.failures
            if len(failures) != track.failures:
                for failure in failures[track.failures :]:
                    self._event(f"{log.name}: {fault_text(log.spec.chassis.chassis, failure)}", "WARN")
                track.failures = len(failures)
        if len(log.notes) != track.notes:  # a new kind of projected command: its first message
            for message, _ in list(log.notes.values())[track.notes :]:
                self._event(f"{log.name}: note: {message}", "WARN")
            track.notes = len(log.notes)
        if robot.fallen and not track.fell:
            track.fell = True
            self._event(f"{log.name}: fell into a hole at ({robot.pose[0]:.3f}, {robot.pose[1]:.3f}) m", "ERROR")
        if log.goal_time is not None and not track.goal:  # (said once, when it happens, in the words of the end's outcome)
            track.goal = True
            self._event(f"{log.name}: {log.goal_outcome(log.goal_time)}", "INFO")

    def _send_all(self, count: int) -> None:
        """Send every robot's samples up to `count` (what the run has logged completely)."""
        for track in self._tracks:
            if count > track.start:
                self._send(track, count)
        self._sent = count

    def on_end(self, result: RunResult) -> None:
        """Note how the run ended, flush what is buffered and close (also after an error or Ctrl-C)."""
        if self.streams:
            level = "ERROR" if result.reason.failed else "WARN" if result.reason.signalled else "INFO"
            if result.world.goals:  # (whether, said plainly, last before the end: a goal reached was said when it was)
                for log, track in zip(result.robots, self._tracks):
                    if not track.goal:
                        self._event(f"{log.name}: {log.goal_outcome(result.duration)}", "INFO" if log.goal_time is not None else "WARN")
            self._event(f"end: {result.reason}" + (f": {result.error}" if result.error else ""), level)
        self.close()

    def close(self) -> None:
        """Send the buffered samples and finish the recording; safe to call twice."""
        if self._messages is not None:
            logging.getLogger().removeHandler(self._messages)
            self._messages = None
        if not self.streams:
            return
        try:
            self._send_all(len(self._tracks[0].log) if self._tracks else 0)
            if self._live is not None:
                self._check_live()
        finally:
            failed: Exception | None = None
            for k, rec in enumerate(self.streams):  # (the file's stream first, where there is one)
                failed = _finish(rec, self.path if k == 0 else None) or failed
            if self.streams and self.path is not None and not recording_whole(self.path):  # (rerun says why on its log, silenced: `quiet_rerun`)
                self.write_error = f"{self.path}: {trouble(self.path) or failed or 'rerun stopped writing it before its end'}"
            self.streams, self._live = [], None

    # --- streams ----------------------------------------------------------------------------

    def _log(self, path: str, data: Any, static: bool = False) -> None:
        for rec in self.streams:
            rec.log(path, data, static=static)

    def _columns(self, path: str, times: list, columns: Any) -> None:
        times, columns = [ArrowOwned(t) for t in times], [ArrowOwned(c) for c in columns]
        for rec in self.streams:
            rec.send_columns(path, times, columns)

    def _event(self, text: str, level: str) -> None:
        rr = lazy_rerun()
        for rec in self.streams:
            rec.set_time(TIMELINE, duration=self._now)
            rec.log("events", rr.TextLog(text, level=level))

    # --- internals ------------------------------------------------------------------------

    def _track(self, log: RobotLog) -> _Track:
        spec = log.spec
        channels, picks = zip(*(field_channels(spec, f) for f in FIELDS))
        return _Track(
            log=log,
            estimates=log.estimate_names,
            ir=np.array([(*s.position, s.direction) for s in getattr(spec, RAYS.section)]).reshape(-1, 3),
            channels=list(channels),
            picks=list(picks),
            buffered=spec.chassis is not None,
        )

    def _facts_text(self, world: World, logs: list[RobotLog]) -> str:
        import sim

        rows = [
            ("world", f"{world.spec.name} ({world.spec.source or 'built in'})"),
            ("seed", str(world.seed)),
            ("dt", f"{1000 * world.dt:g} ms"),
            *((key, str(value)) for key, value in self.facts.items()),
            ("ctsim", sim.__version__),
            ("recorded", time.strftime("%Y-%m-%d %H:%M:%S")),
        ]
        lines = [f"# {world.spec.name}", "", "| | |", "|---|---|", *(f"| {k} | {v} |" for k, v in rows), ""]
        for log in logs:
            params = ", ".join(f"{k}={v}" for k, v in log.params.items()) or "defaults"
            lines += [f"## {log.name}", "", f"- robot: {log.spec.name}", f"- controller: {log.controller_name} ({params})", f"- estimates: {', '.join(log.estimate_names)}", ""]
        return "\n".join(lines)

    def _style(self) -> None:
        """Static parts: each robot's outline in its body frame, the estimates' markers, the
        colours of trails and plot series (the data itself is temporal)."""
        rr = lazy_rerun()
        several = len(self._tracks) > 1
        for track in self._tracks:
            name, spec = track.log.name, track.log.spec
            base = f"world/{name}"
            outline = body_outline(spec)
            heading = [(0.0, 0.0), (outline[:, 0].max() + 0.35 * spec.body_radius, 0.0)]
            own = rgb(self.colours.get(name, palette.TRUTH))
            self._log(f"{base}/body/outline", rr.LineStrips2D([outline, heading], colors=own, radii=-2.0, draw_order=60), static=True)
            if name in self.colours:
                self._log(f"{base}/body/name", light_labels([(0.0, 0.0)], [name], draw_order=-101.0), static=True)  # (its point beneath the floor)
            self._log(f"{base}/rays", rr.LineStrips2D.from_fields(colors=rgb(palette.RAY), radii=-0.75, draw_order=55), static=True)
            self._log(f"{base}/hits", rr.Points2D.from_fields(colors=rgb(palette.HIT), radii=-2.5, draw_order=56), static=True)
            self._log(f"{base}/trail/truth", rr.LineStrips2D.from_fields(colors=own, radii=-2.5, draw_order=48), static=True)
            colours = [rgb(palette.estimate_colour(label, track.estimates)) for label in track.estimates]
            for label, colour in zip(track.estimates, colours):
                self._log(f"{base}/trail/{label}", rr.LineStrips2D.from_fields(colors=colour, radii=-1.0, draw_order=50), static=True)
                self._log(f"{base}/estimate/{label}/outline", rr.LineStrips2D([0.6 * outline, 0.75 * np.array(heading)], colors=colour, radii=-1.2, draw_order=58), static=True)
            if track.estimates:  # one entity per kind of error, a series per estimate (one column each to send)
                who = [f"{name} {label}" if several else label for label in track.estimates]
                self._log(f"errors/{name}/position", rr.SeriesLines(colors=colours, names=who, widths=error_widths(len(who))), static=True)
                self._log(f"errors/{name}/heading", rr.SeriesLines(colors=colours, names=who, widths=error_widths(len(who))), static=True)
            uncertain = track.log.uncertain_names
            if uncertain:
                band = [rgb(palette.estimate_colour(label, track.estimates)) for label in uncertain]
                for label, colour in zip(uncertain, band):
                    self._log(f"{base}/ellipse/{label}", rr.LineStrips2D.from_fields(colors=colour, radii=-0.8, draw_order=49), static=True)
                for path, sign in (("position/band", ""), ("heading/band_upper", "+"), ("heading/band_lower", "-")):
                    names = [f"{name} {label} {sign}3σ" if several else f"{label} {sign}3σ" for label in uncertain]
                    self._log(f"errors/{name}/{path}", rr.SeriesLines(colors=band, names=names, widths=0.6), static=True)
            for group, (_, fields) in SENSOR_GROUPS.items():
                for f in fields:
                    sides = track.channels[FIELDS.index(f)]
                    width = len(sides)
                    if width:
                        colours = [palette.CHANNELS[(i + 2 * fields.index(f)) % len(palette.CHANNELS)] for i in range(width)]
                        self._log(f"sensors/{group}/{name}/{f}", rr.SeriesLines(colors=colours, names=list(sides), widths=1.0), static=True)  # (a plot per robot)

    def _key(self) -> list[tuple[str, palette.RGB, float]]:
        """The map's key, (label, colour, line radius in points) top down: each robot's truth
        ("truth" for a lone robot, else its name), each estimate once (its colour is the same for
        every robot, on the map and in the error plots), and the error plots' thin 3σ bands."""
        truths = [(track.log.name if len(self._tracks) > 1 else "truth", self.colours.get(track.log.name, palette.TRUTH), 4.0) for track in self._tracks]
        estimates = {label: palette.estimate_colour(label, track.estimates) for track in self._tracks for label in track.estimates}
        banded = any(track.log.uncertain_names for track in self._tracks)
        return [*truths, *((label, colour, 4.0) for label, colour in estimates.items()), *([(BAND_LABEL, palette.KEY_NOTE, 1.0)] if banded else [])]

    def _send(self, track: _Track, stop: int) -> None:
        """Send one robot's samples [track.start, stop) as columns."""
        rr = lazy_rerun()
        name = track.log.name
        base = f"world/{name}"
        span = slice(track.start, stop)
        n = stop - track.start
        at = track.log.time_array(span)
        times = [rr.TimeColumn(TIMELINE, duration=at)]
        truth = track.log.truth_array(span)
        estimates = track.log.estimate_arrays(span)
        readings = track.columns(stop)

        self._columns(f"{base}/body", times, rr.Transform3D.columns(translation=xyz(truth), quaternion=turn(truth[:, 2])))
        for label, poses in estimates.items():
            self._columns(f"{base}/estimate/{label}", times, rr.Transform3D.columns(translation=xyz(poses), quaternion=turn(poses[:, 2])))
        if estimates:
            error = np.stack(list(estimates.values()), axis=1) - truth[:, None]  # (n, estimates, 3)
            per_sample = np.full(n, error.shape[1])
            self._columns(f"errors/{name}/position", times, rr.Scalars.columns(scalars=(1000 * np.hypot(error[..., 0], error[..., 1])).ravel()).partition(per_sample))
            self._columns(f"errors/{name}/heading", times, rr.Scalars.columns(scalars=np.degrees(wrap_angle(error[..., 2])).ravel()).partition(per_sample))
        self._send_trails(track, at, truth, estimates)
        covariances = track.log.covariance_arrays(span)
        if covariances:
            self._send_uncertainty(track, times, at, {label: estimates[label] for label in covariances}, covariances)
        if self._chassis is not None:
            self._chassis.flush(name)
        if self._particles is not None:
            self._particles.flush(name)
        if len(track.ir):
            self._send_rays(track, times, truth, readings[RAYS.field])
        for group, (_, fields) in SENSOR_GROUPS.items():
            for f in fields:
                if f not in readings:
                    continue
                values = readings[f]
                if BY_FIELD[f].angle:  # from straight, as `chassis_view.steering_deflection`
                    values = wrap_angle(values - track.log.spec.chassis.chassis.beta[track.picks[FIELDS.index(f)]])
                self._columns(f"sensors/{group}/{name}/{f}", times, rr.Scalars.columns(scalars=(values * SCALE.get(f, 1.0)).ravel()).partition(np.full(n, values.shape[1])))
        track.start = stop
        track.count = 0

    def _send_trails(self, track: _Track, at: np.ndarray, truth: np.ndarray, estimates: dict[str, np.ndarray]) -> None:
        """Trail pieces of TRAIL_EVERY samples (sent at times `at`), each starting where the last
        ended; the truth's split before each sample the robot stood where it was put down
        (`RobotLog.puts`: a hand, not its motion, took it there). An estimate's trail is never
        split: the estimate does not jump when the robot is put down (its odometry does not see
        it), and where it does jump, a localiser finding itself again, that jump is what the
        robot believed, and drawn."""
        rr = lazy_rerun()
        n = len(truth)
        points = np.stack([truth[:, :2], *(poses[:, :2] for poses in estimates.values())], axis=1)  # (n, labels, 2)
        ends = np.arange(TRAIL_EVERY - 1 - track.start % TRAIL_EVERY, n, TRAIL_EVERY)
        if len(ends) == 0 or ends[-1] != n - 1:
            ends = np.append(ends, n - 1)  # the trail reaches the last sample sent (the run's end, or a live send)
        if len(ends) == 0:
            return
        times = [rr.TimeColumn(TIMELINE, duration=at[ends])]
        # piece j is samples ends[j-1]..ends[j] (the first: the last chunk's end, or none, then 0..ends[0])
        joined = track.tail is not None
        first = np.concatenate(([0], ends[:-1] + joined))
        puts = np.asarray(track.log.puts, dtype=np.int64)
        cuts = puts[(puts >= track.start) & (puts < track.start + n)] - track.start + joined  # (in the points with the tail)
        plain = trail_pieces(first, ends + joined, np.empty(0, np.int64))
        for k, label in enumerate(["truth", *estimates]):
            along = np.concatenate((track.tail[k : k + 1], points[:, k])) if joined else points[:, k]
            rows, offsets, counts = trail_pieces(first, ends + joined, cuts) if k == 0 and len(cuts) else plain
            self._columns(f"world/{track.log.name}/trail/{label}", times, rr.LineStrips2D.columns(strips=strips(along[rows], offsets)).partition(counts))
        track.tail = points[ends[-1]].copy()

    def _send_uncertainty(self, track: _Track, times: list, at: np.ndarray, estimates: dict[str, np.ndarray], covariances: dict[str, np.ndarray]) -> None:
        """The 3 sigma bands of the error plots, and every ELLIPSE_EVERY samples each estimate's
        95 % position ellipse: `covariances` label -> (n, 6) COVARIANCE_FIELDS entries of the
        samples at times `at` (s; `times` their time column)."""
        rr = lazy_rerun()
        name = track.log.name
        entries = np.stack(list(covariances.values()), axis=1)  # (n, labels, 6)
        n, k = entries.shape[:2]
        xx, xy, yy, tt = entries[..., 0], entries[..., 1], entries[..., 3], entries[..., 5]
        major = 0.5 * (xx + yy) + np.sqrt(0.25 * (xx - yy) ** 2 + xy**2)  # the larger eigenvalue
        per_sample = np.full(n, k)
        self._columns(f"errors/{name}/position/band", times, rr.Scalars.columns(scalars=(3000 * np.sqrt(np.maximum(major, 0))).ravel()).partition(per_sample))
        heading = 3 * np.degrees(np.sqrt(np.maximum(tt, 0))).ravel()
        self._columns(f"errors/{name}/heading/band_upper", times, rr.Scalars.columns(scalars=heading).partition(per_sample))
        self._columns(f"errors/{name}/heading/band_lower", times, rr.Scalars.columns(scalars=-heading).partition(per_sample))
        picked = np.flatnonzero((track.start + np.arange(n)) % ELLIPSE_EVERY == 0)
        if not len(picked):
            return
        when = [rr.TimeColumn(TIMELINE, duration=at[picked])]
        for j, (label, poses) in enumerate(estimates.items()):
            rings = ellipses(poses[picked, :2], entries[picked, j])
            offsets = np.arange(0, len(picked) * ELLIPSE_POINTS + 1, ELLIPSE_POINTS)
            self._columns(f"world/{name}/ellipse/{label}", when, rr.LineStrips2D.columns(strips=strips(rings.reshape(-1, 2), offsets)))

    def _send_rays(self, track: _Track, times: list, truth: np.ndarray, distance: np.ndarray) -> None:
        """IR rays from each sensor to the distance it reports (`distance` (n, k) m, nan: nothing
        seen: a ray of full length) and the points hit."""
        rr = lazy_rerun()
        n, k = len(truth), len(track.ir)
        c, s = np.cos(truth[:, 2])[:, None], np.sin(truth[:, 2])[:, None]
        x, y, direction = track.ir.T
        origin = np.stack((truth[:, :1] + c * x - s * y, truth[:, 1:2] + s * x + c * y), axis=-1)
        hit = np.isfinite(distance)
        reach = np.where(hit, distance, IR_RAY_LENGTH)[..., None]
        angle = truth[:, 2:3] + direction
        end = origin + reach * np.stack((np.cos(angle), np.sin(angle)), axis=-1)
        rays = np.stack((origin, end), axis=2).reshape(2 * n * k, 2)  # each ray from its sensor to its end
        self._columns(f"world/{track.log.name}/rays", times, rr.LineStrips2D.columns(strips=strips(rays, np.arange(0, 2 * n * k + 1, 2))).partition(np.full(n, k)))
        self._columns(f"world/{track.log.name}/hits", times, rr.Points2D.columns(positions=end[hit]).partition(hit.sum(axis=1)))


def trail_pieces(first: np.ndarray, last: np.ndarray, cuts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A trail's rows of line strips: row j the points first[j]..last[j] (indices into the
    trail's points), split before each point in `cuts` (its line from the point before is not
    drawn). (points' indices of every strip in turn, the strips' offsets in those, strips per
    row) as `strips` and `partition` take them."""
    row = np.concatenate((np.arange(len(first)), np.searchsorted(last, cuts)))  # (a cut's row: the one with its line)
    begin = np.concatenate((first, cuts))
    order = np.lexsort((begin, row))
    row, begin = row[order], begin[order]
    end = np.append(begin[1:] - 1, 0)
    closes = np.append(row[1:] != row[:-1], True)  # the last strip of its row ends where the row does
    end[closes] = last[row[closes]]
    kept = end >= begin  # (not a cut at a row's first point)
    row, begin, end = row[kept], begin[kept], end[kept]
    lengths = end - begin + 1
    offsets = np.concatenate(([0], np.cumsum(lengths)))
    return np.arange(offsets[-1]) + np.repeat(begin - offsets[:-1], lengths), offsets, np.bincount(row, minlength=len(first))


def _finish(rec: Any, path: Path | None) -> Exception | None:
    """Flush and close a recording stream, in a thread of its own (rerun's file writer, once dead,
    can leave both waiting for ever): waited for while its file at `path` grows, and after it
    stopped growing STALL_S where its disk is full or its size limit reached (`trouble`), else
    FLUSH_WAIT_S (no file: FLUSH_WAIT_S in all). What failed (rerun's writer died: what it wrote
    stays), if anything."""
    failed: list[RuntimeError] = []

    def end() -> None:
        try:
            rec.flush(timeout_sec=FLUSH_WAIT_S)
            rec.disconnect()
        except RuntimeError as err:  # rerun's file writer died (disk full, I/O error): what it wrote stays
            failed.append(err)

    thread = threading.Thread(target=end, name="ctsim recording's end", daemon=True)
    thread.start()
    size, since = _size(path), time.monotonic()
    while thread.join(0.25) or thread.is_alive():
        if (now := _size(path)) != size:
            size, since = now, time.monotonic()
        elif time.monotonic() - since > FLUSH_WAIT_S or (time.monotonic() - since > STALL_S and path is not None and trouble(path)):
            lazy_rerun().unregister_shutdown()  # (rerun's own end at the process's exit would wait for it too)
            return TimeoutError("rerun stopped writing it and did not finish")
    return failed[0] if failed else None


def _size(path: Path | None) -> int:
    """The size of the file at `path` (-1: none, or unreadable)."""
    try:
        return os.stat(path).st_size if path is not None else -1
    except OSError:
        return -1


class _Messages(logging.Handler):
    """Controller messages: Python `logging` records of INFO and above emitted during the run go
    to the events log at the simulated time they were emitted."""

    def __init__(self, recorder: Recorder):
        super().__init__(logging.INFO)
        self.recorder = recorder

    def emit(self, record: logging.LogRecord) -> None:
        level = {"WARNING": "WARN", "CRITICAL": "ERROR"}.get(record.levelname, record.levelname)
        self.recorder._event(f"{record.name}: {record.getMessage()}", level)


def recording_whole(path: Path) -> bool:
    """Whether the recording at `path` ends with rerun's footer: one cut short (a full disk, the
    file-size limit, a writer that died) does not, and rerun said so only on its log, if at all."""
    try:
        with open(path, "rb") as file:
            file.seek(max(os.fstat(file.fileno()).st_size - 4 * len(FOOTER), 0))
            return FOOTER in file.read()
    except OSError:
        return False
