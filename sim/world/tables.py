"""The tables the World hands its compiled kernels (`sim.world.layout`), built from its robots (its
`sim.world.physics.Robot`s: `Any` here, as that module builds on this one) and
walls: per-robot parameters and state, every sensor, the walls and their grid, the IR curves and
the noisy sensors' generators."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pymunk

from bots.ir_curve import IRCurve
from bots.readings import SensorLayout
from bots.sensor_kinds import FRAMED, FRAMES
from bots.spec import RobotSpec
from sim.kinematics import counts_per_metre
from sim.world import layout
from sim.world.kernels.grids import gridded
from sim.world.noise import NormalBlocks
from sim.world.sensors import CNY70_MAX, LDR_MAX
from sim.world.spec import WorldSpec

SLOP = 0.0005
"""pymunk collision slop for a world in metres (its default 0.1 assumes pixels)."""


SWEEP_CLEARANCE = 1.5 * SLOP
"""A move is cut where the body would sink deeper than this into another body."""


SLIDE_MARGIN = 0.2 * SLOP
"""The sweep of a slide along a surface just touched uses a circle thinner by this (m)."""


IR_RAY_LENGTH = 0.85
"""How far an IR ray is cast (m), c't-Sim's pick distance; beyond it nothing is seen."""


@dataclass(frozen=True)
class Noisy:
    """The sensors of one kind that have noise: their rows in the kind's values, their standard
    deviations and their generators' normals."""

    rows: np.ndarray
    std: np.ndarray
    normals: NormalBlocks
    sensors: tuple[tuple[int, str], ...]
    """(robot index, sensor name) of each row of `normals`, to seed a robot's rows anew."""

    @classmethod
    def of(cls, items: list[tuple[int, Any, str, float]]) -> Noisy:
        """From (row, robot, sensor name, std) per noisy sensor."""
        return cls(
            rows=np.array([k for k, _, _, _ in items], dtype=np.int64),
            std=np.array([std for _, _, _, std in items], dtype=np.float64),
            normals=NormalBlocks([robot.rngs[name] for _, robot, name, _ in items]),
            sensors=tuple((robot.index, name) for _, robot, name, _ in items),
        )

    @property
    def kernel(self) -> layout.Noise:
        """Its rows, standard deviations and normals as the kernels take them (`kernels.noise`, the IR kernel)."""
        return layout.Noise(self.rows, self.std, self.normals.values, self.normals.used)

    def reseed(self, robot: Any) -> None:
        """Draw `robot`'s rows from its (new) generators from now on."""
        for k, (index, name) in enumerate(self.sensors):
            if index == robot.index:
                self.normals.restart(k, robot.rngs[name])


WALL_GRID_ABOVE = 128
"""Walls a world has before the kernels look them up in a grid: up to this many, one cell holds
them all, as checking every wall's box (a compiled loop, a fraction of a nanosecond a box) costs
no more than finding the cells. Measured with one c't-Bot reading every sensor in generated
mazes: a step costs the same either way at 82 and 133 walls; the grid saves about 5% at 329
walls, 10-15% at 934 and 40% at 3,780, where its step costs what one among 22 walls does."""


WALLS_PER_CELL = 2.0
"""The wall grid's cells hold this many walls on average (`wall_cell`)."""


def wall_cell(boxes: np.ndarray) -> float:
    """The side (m) of the wall grid's square cells for walls of BOXES `boxes`:
    cells of WALLS_PER_CELL walls' share of the walls' extent, so that the grid has about
    n / WALLS_PER_CELL cells whatever the world's size and a query meets the walls near it; at
    least 1/n of the extent's longer side (a thin extent has n cells at most along it)."""
    n = len(boxes)
    if n == 0:
        return 1.0
    width, height = boxes["xmax"].max() - boxes["xmin"].min(), boxes["ymax"].max() - boxes["ymin"].min()
    return max(math.sqrt(WALLS_PER_CELL * width * height / n), max(width, height) / n, 1e-9)


def walls_of(spec: WorldSpec) -> layout.Walls:
    """The walls as flat arrays for the kernels: all vertices, each wall's SPANS of them, its BOXES
    and a uniform grid over the boxes (`kernels.grids.build_wall_grid`; walls are static, so it is
    built once)."""
    polygons = [np.asarray(w.vertices, dtype=np.float64) for w in spec.walls]
    spans, boxes = layout.SPANS.new(len(polygons)), layout.BOXES.new(len(polygons))
    spans["end"] = np.cumsum([len(p) for p in polygons], dtype=np.int64)
    spans["start"] = spans["end"] - np.array([len(p) for p in polygons], dtype=np.int64)
    for name, values in zip(("xmin", "ymin", "xmax", "ymax"), np.array([(*p.min(axis=0), *p.max(axis=0)) for p in polygons]).reshape(-1, 4).T):
        boxes[name] = values
    boxes["cylinder"] = [w.cylinder for w in spec.walls]
    vertices = np.concatenate(polygons).reshape(-1, 2) if polygons else np.zeros((0, 2))
    return gridded(vertices, spans, boxes, wall_cell(boxes) if len(boxes) > WALL_GRID_ABOVE else math.inf)  # one cell: the plain loop


def _contacts(spec: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    """The ground contacts the hole rule checks (body frame, m) and which of them c't-Sim checks at
    the robot's old position: the c't-Bot's wheels (old position) and skid (new position); every
    wheel of a general chassis (new position)."""
    if spec.chassis is None:
        points = np.array(((0.0, spec.track_width / 2), (0.0, -spec.track_width / 2), spec.skid))
        return points, np.array((True, True, False))
    points = np.asarray(spec.chassis.chassis.positions, dtype=np.float64)
    return points, np.zeros(len(points), dtype=bool)


def _padded(rows: list[np.ndarray], dtype: type, tail: tuple[int, ...] = ()) -> np.ndarray:
    """Per-robot contact arrays stacked to the longest one, each padded by repeating its own rows."""
    width = max((len(r) for r in rows), default=1)
    return np.array([r[np.arange(width) % len(r)] for r in rows], dtype=dtype).reshape(len(rows), width, *tail)


class RobotTables:
    """Per-robot parameters and state as arrays for the kernels (rebuilt when a robot joins):
    packed into a few 2-D arrays in the column layout of `sim.world.layout` (one argument each
    per kernel call), with named views of the columns the Python side uses."""

    def __init__(self, robots: list[Any], dt: float, movable_shapes: list[pymunk.Circle], robots_meet: bool = True):
        n = len(robots)
        specs = [r.spec for r in robots]
        motor = [s.motor for s in specs]
        self.robots = p = layout.ROBOTS.new(n)
        p["command_max"] = [m.command_max for m in motor]
        p["max_speed"] = [m.max_wheel_speed for m in motor]
        p["lag"] = [1.0 - math.exp(-dt / m.time_constant) if m.time_constant > 0 else 1.0 for m in motor]
        p["max_change"] = [m.max_acceleration * dt for m in motor]
        p["ticks_per_rad"] = [s.encoders.ticks_per_rev / (2 * math.pi) for s in specs]
        p["real_radius"] = np.array([[s.wheel_radius * (1 + e) for e in s.encoders.diameter_error] for s in specs]).reshape(n, 2)
        p["track"] = [s.track_width * (1 + s.encoders.track_error) for s in specs]
        p["mount"] = np.array([s.mouse.mount if s.mouse else (0.0, 0.0) for s in specs], dtype=np.float64).reshape(n, 2)
        p["counts_per_metre"] = [counts_per_metre(s.mouse.dpi) * (1 + s.mouse.scale_error) if s.mouse else 0.0 for s in specs]
        p["max_step"] = [s.mouse.max_speed * dt if s.mouse else 0.0 for s in specs]
        p["sweep_radius"] = [s.body_radius - SWEEP_CLEARANCE for s in specs]
        p["apart_radius"] = [s.body_radius - SWEEP_CLEARANCE / 2 for s in specs]
        p["mass"] = [r.body.mass for r in robots]
        p["moment"] = [r.body.moment for r in robots]
        p["radius"] = [s.body_radius for s in specs]
        p["stops"] = [s.contact == "stop" for s in specs]
        self.stoppers = np.flatnonzero(p["stops"])
        """The robots with c't-Sim's contact rule (a refused move counts as a collision)."""
        self.contacts = _padded([_contacts(s)[0] for s in specs], np.float64, (2,))
        self.anchored = _padded([_contacts(s)[1] for s in specs], np.bool_)
        self.state = layout.STATE.new(n)
        for robot in robots:
            self.start_counters(robot)
        self.slip, self.mouse_noise, self.move, self.alpha = (self.state[name] for name in ("slip", "mouse_noise", "move", "alpha"))
        self.tallies = np.zeros((n, 4), dtype=np.int64)
        """Encoder ticks then mouse counts of the last step (what `World.tallies` gives)."""
        self.tally_rows = layout.tally_rows(self.tallies)
        """The same as TALLIES rows, for the kernels."""
        self.fallen = np.array([r.fallen for r in robots], dtype=np.bool_)
        encoders = [r for r in robots if r.spec.encoders.slip_std or r.spec.encoders.tick_noise]
        mice = [r for r in robots if r.spec.mouse is not None and r.spec.mouse.noise_std]
        self.step_noise = Noisy.of([(r.index, r, "encoders", r.spec.encoders.slip_std) for r in encoders]
                                   + [(r.index, r, "mouse", r.spec.mouse.noise_std * p["counts_per_metre"][r.index]) for r in mice])
        """What a step draws before it moves (`kernels.noise.draw_step`): rows of the robots whose
        encoders slip or miscount (std: their slip_std), then of those whose mouse has count noise
        (std: noise_std (sqrt m) at the counts' own scale, counts per sqrt m)."""
        self.encoders = len(encoders)
        """How many of `step_noise`'s rows are encoders'."""
        self.tick_noise = np.array([r.spec.encoders.tick_noise for r in encoders], dtype=np.float64)
        self.tick_uniforms = np.zeros((len(encoders), 4))
        """The step's uniforms of each noisy encoder's spurious ticks."""
        self.spurious_ticks = bool(self.tick_noise.any())

        floor, light, ir = (_framed_sensors(robots, frame.name) for frame in FRAMES if frame.row == "values")  # (SENSORS' order)
        self.ir_sensors = ir
        self.n_floor, self.n_light = len(floor), len(light)
        every = floor + light + ir
        self.sensors = layout.SENSORS.new(len(every))
        rows = self.sensors
        rows["at"] = np.array([s.position for _, s in every], dtype=np.float64).reshape(-1, 2)
        rows["height"][: len(floor) + len(light)] = [s.height for _, s in floor + light]
        rows["direction"][len(floor) :] = [s.direction for _, s in light + ir]
        rows["opening"][len(floor) :] = [s.opening / 2 for _, s in light] + [s.cone for _, s in ir]
        rows["reach"][len(floor) : len(floor) + len(light)] = [s.reach for _, s in light]
        rows["pick"][len(floor) :] = [s.view == "pick" for _, s in (*light, *ir)]

        def noisy(items):
            return Noisy.of([(k, robot, s.name, s.noise_std) for k, (robot, s) in enumerate(items) if s.noise_std])

        self.floor_and_light_noise = noisy(floor + light)
        """The noisy floor (line, border) and light sensors: their rows in the values of both."""
        self.floor_and_light_top = np.where(self.floor_and_light_noise.rows < len(floor), CNY70_MAX, LDR_MAX).astype(np.int64)
        """Each one's highest value (`kernels.noise.add_rounded`)."""
        self.ir = _IRArrays.build(ir, noisy(ir))
        rows["owner"] = [r.index for r, _ in every]
        rows["noise_row"][len(floor) + len(light) :] = self.ir.noise_row
        rows["curve"][len(floor) + len(light) :] = self.ir.curve
        owners = [r.index if robots_meet else layout.GHOST for r in robots if isinstance(r.shape, pymunk.Circle)] + [-1] * len(movable_shapes)
        self.circles = layout.CIRCLES.new(len(owners))
        self.circles["radius"] = [r.shape.radius for r in robots if isinstance(r.shape, pymunk.Circle)] + [shape.radius for shape in movable_shapes]
        self.circles["owner"] = owners
        """Robots then movable obstacles as CIRCLES for the IR kernel; positions are filled in at each read."""
        self.layout = SensorLayout.of([{kind.field: kind.width(s) for kind in FRAMED} for s in specs])

    def start_counters(self, robot: Any) -> None:
        """`robot`'s counters' carries at their start phases (`physics.start_phases`)."""
        self.state["tick_carry"][robot.index] = robot.phases[:2]
        self.state["mouse_carry"][robot.index] = robot.phases[2:]

    def reseed(self, robot: Any) -> None:
        """Draw `robot`'s noise from its (new) generators from now on."""
        for noisy in (self.step_noise, self.floor_and_light_noise, self.ir.noise):
            noisy.reseed(robot)


@dataclass(frozen=True)
class _IRArrays:
    """The IR sensors' noise and curves as arrays for the kernels: each distinct (curve, range)'s
    tables padded into one 2-D array per kind (the mounts are in `RobotTables.sensors`)."""

    noise: Noisy
    noise_row: np.ndarray
    """Each sensor's row in `noise` (-1: none)."""
    curve: np.ndarray
    """Each sensor's index into the tables below."""
    tables: np.ndarray
    curve_ends: np.ndarray
    """Per curve: the last centimetre of its table and its lowest raw value (CURVE_ENDS)."""
    beyond: np.ndarray
    inverse: np.ndarray

    @property
    def curves(self) -> layout.Curves:
        """The curves as `kernels.sensing.ir_values` takes them."""
        return layout.Curves(IR_RAY_LENGTH, self.tables, self.curve_ends, self.beyond, self.inverse)

    @classmethod
    def build(cls, ir: list[tuple[Any, object]], noise: Noisy) -> _IRArrays:
        n = len(ir)
        index: dict[tuple, int] = {}
        chosen: list[tuple[IRCurve, float, float]] = []
        curve = np.empty(n, dtype=np.int64)
        for k, (robot, sensor) in enumerate(ir):
            table = robot.ir_curves[robot.spec.ir.index(sensor)]
            key = (id(table), sensor.min_range, sensor.max_range)
            if key not in index:
                index[key] = len(chosen)
                chosen.append((table, sensor.min_range, sensor.max_range))
            curve[k] = index[key]
        per_cm = [table.per_cm for table, _, _ in chosen]
        inverse = [table.inverse_table(low, high) for table, low, high in chosen]
        tables = np.zeros((len(chosen), max((len(t) for t in per_cm), default=1)), dtype=np.float32)
        inverses = np.zeros((len(chosen), max((len(t) for t in inverse), default=1)))
        for c, (t, v) in enumerate(zip(per_cm, inverse)):
            tables[c, : len(t)] = t
            inverses[c, : len(v)] = v
        noise_row = np.full(n, -1, dtype=np.int64)
        noise_row[noise.rows] = np.arange(len(noise.rows))
        return cls(
            noise=noise,
            noise_row=noise_row,
            curve=curve,
            tables=tables,
            curve_ends=_curve_ends([(len(t) - 1, table.raw_range()[0]) for t, (table, _, _) in zip(per_cm, chosen)]),
            beyond=np.array([table.beyond for table, _, _ in chosen], dtype=np.float32),
            inverse=inverses,
        )


def _curve_ends(ends: list[tuple[int, int]]) -> np.ndarray:
    """CURVE_ENDS rows of (last, lowest) pairs."""
    rows = layout.CURVE_ENDS.new(len(ends))
    if ends:
        rows["last"], rows["lowest"] = zip(*ends)
    return rows


def _framed_sensors(robots: list[Any], frame: str) -> list[tuple[Any, Any]]:
    """(robot, sensor) of every sensor whose kind the registry packs into the `frame` array, robot
    after robot, each robot's in the registry's order (`bots.readings.SensorLayout`)."""
    kinds = [kind for kind in FRAMED if kind.frame == frame and kind.section is not None]
    return [(r, s) for r in robots for kind in kinds for s in getattr(r.spec, kind.section)]
