"""World benchmarks: steps per second of whole simulation steps (sensors, control, physics)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from bots.ctbot import CTBOT
from bots.noise import DEFAULT_NOISE, with_noise
from sim.world import World
from sim.world.files import load_world
from sim.world.spec import Start, Wall, WorldSpec

Measured = TypeVar("Measured")


def _steps_per_second(world: World, steps: int, commands: np.ndarray, read: bool = True, repeats: int = 3) -> float:
    """Best of `repeats` timed runs of `steps` steps (as timeit: the others met a busy machine),
    after a warm-up in which compiled kernels and caches settle in."""

    def advance(count: int) -> None:
        for _ in range(count):
            if read:
                world.read_all()
            world.step(commands)

    advance(min(steps, 2000))
    best = 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        advance(steps)
        best = max(best, steps / (time.perf_counter() - start))
    return best


def empty_1bot(steps: int) -> float:
    """One robot with no sensors in an empty world, driving a circle."""
    bare = CTBOT.with_changes(name="bare", mouse=None, ir=(), line=(), border=(), light=())
    world = World(WorldSpec("empty", (-5, -5, 5, 5), starts=(Start(0, 0, 0),)))
    world.add_robot(bare)
    return _steps_per_second(world, steps, np.array([[120.0, 160.0]]), read=False)


def mecanum_4wheel(steps: int) -> float:
    """`empty_1bot` for the Mecanum-4 robot (general chassis drive: motors, least-squares forward
    kinematics, exact SE(2) step, four encoders), crabbing along a curve."""
    from bots.wheeled import MECANUM4
    from sim.kinematics.chassis import inverse_kinematics

    bare = MECANUM4.with_changes(name="bare", mouse=None, ir=(), chassis={"mouse2": None})
    world = World(WorldSpec("empty", (-5, -5, 5, 5), starts=(Start(0, 0, 0),)))
    world.add_robot(bare)
    wheels = inverse_kinematics(bare.chassis.chassis, [0.3, 0.2, 0.4])
    world.chassis.command(0, wheels.phi_dot, wheels.beta)
    return _steps_per_second(world, steps, np.zeros((1, 2)), read=False)


def maze_ctbot(steps: int, repeats: int = 3, noise: str = "none") -> float:
    """One c't-Bot reading every sensor each step in the shipped maze, turning gently so that it
    meets walls (contacts, sliding and ray hits included), with a noise preset (`bots.noise`)."""
    world = World(load_world("maze"))
    world.add_robot(with_noise(CTBOT, noise))
    return _steps_per_second(world, steps, np.array([[200.0, 180.0]]), repeats=repeats)


def noise_over_exact(steps: int, rounds: int = 5) -> float:
    """Cost of `maze_ctbot`'s step with the default (realistic) noise over the exact one: the best
    of `rounds` interleaved runs of each (noise draws in the compiled kernels; bar <= 1.25)."""
    best = {"none": 0.0, DEFAULT_NOISE: 0.0}
    for _ in range(rounds):
        for preset in best:
            best[preset] = max(best[preset], maze_ctbot(steps, repeats=1, noise=preset))
    return best["none"] / best[DEFAULT_NOISE]


def generated_maze(rooms: int, seed: int = 0) -> WorldSpec:
    """A perfect maze of rooms x rooms one-cell rooms in the shipped maze's tiles (0.24 m cells,
    walls a cell thick), carved by a seeded depth-first walk: 934 wall boxes at 40 rooms a side."""
    from sim.world.files.grid import build_grid

    rng = np.random.default_rng(seed)
    size = 2 * rooms + 1
    tiles = [["*" if r % 2 == 0 and c % 2 == 0 else "=" if r % 2 == 0 else "#" if c % 2 == 0 else " " for c in range(size)] for r in range(size)]
    seen, path = {(0, 0)}, [(0, 0)]
    while path:
        r, c = path[-1]
        free = [(r + dr, c + dc) for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)) if 0 <= r + dr < rooms and 0 <= c + dc < rooms and (r + dr, c + dc) not in seen]
        if not free:
            path.pop()
            continue
        nr, nc = free[rng.integers(len(free))]
        tiles[r + nr + 1][c + nc + 1] = " "  # the wall tile between the two rooms
        seen.add((nr, nc))
        path.append((nr, nc))
    pieces = build_grid(["".join(row) for row in tiles])
    return WorldSpec(f"maze{rooms}", pieces.bounds, walls=pieces.walls)


def big_maze_ctbot(steps: int, rooms: int = 40) -> float:
    """`maze_ctbot` in a `generated_maze` (~1,000 walls, 19 m a side; a 1 cm floor raster, as a
    2 mm one would take hundreds of MB), starting in a corner room facing along its corridor."""
    world = World(generated_maze(rooms), floor_cell=0.01)
    world.add_robot(CTBOT, (0.36, 0.36, np.pi / 2))
    return _steps_per_second(world, steps, np.array([[200.0, 180.0]]))


def maze_run(steps: int, record: bool, noise: str = DEFAULT_NOISE) -> float:
    """Steps per second of a whole run (`sim.run.loop.run`: sensors, odometry, controller, physics) of
    a c't-Bot with a noise preset (the main job's, realistic) solving the maze for `steps` steps,
    with or without the rerun recorder writing every step to a temporary .rrd (opening and
    closing the file included)."""
    import tempfile
    from pathlib import Path

    from bots.behaviours import make
    from sim.run.loop import RobotSetup, run
    from sim.views.recording.arrow import keep_pandas_out_of_arrow
    from sim.views.recording.recorder import Recorder

    if record:
        keep_pandas_out_of_arrow()  # as `ctsim run` does
    with tempfile.TemporaryDirectory() as folder:
        observers = [Recorder(Path(folder) / "bench.rrd")] if record else []
        start = time.perf_counter()
        result = run(load_world("maze"), [RobotSetup(with_noise(CTBOT, noise), make("solve_maze", {}))], steps * 0.01, observers=observers)
        return (len(result) - 1) / (time.perf_counter() - start)  # the steps run: solve_maze ends at the goal (~240 s)


def run_parts(steps: int, repeats: int = 3) -> dict[str, float]:
    """µs a step of `maze_run`'s parts timed from outside: solve_maze's `step` ("solve_maze"), and
    the run loop's own work ("glue": the sample rows, the readings handed out, the guards, speeds
    into motor commands, goal and status tests), what is left of the run with the world's sensor
    read and step, solve_maze's step and the default odometry taken off, and so is a timed call's
    own cost (a timed call of nothing, measured alongside); a run of one step taken off a run of
    `steps` removes the set-up. Each the best of `repeats`."""
    from time import perf_counter_ns

    from bots.behaviours import make
    from bots.odometry.batch import DefaultOdometry
    from sim.run.loop import RobotSetup, run

    inside = {"solve_maze": 0, "others": 0}

    def timed(call: Callable, part: str = "others") -> Callable:
        def counted(*args, **named):
            start = perf_counter_ns()
            try:
                return call(*args, **named)
            finally:
                inside[part] += perf_counter_ns() - start

        return counted

    def nothing() -> None:
        return None

    def timing_cost() -> float:
        """ns a timed call costs beyond the call itself."""
        bare, wrapped = [], []
        for calls, into in ((nothing, bare), (timed(nothing), wrapped)):
            start = perf_counter_ns()
            for _ in range(100_000):
                calls()
            into.append((perf_counter_ns() - start) / 100_000)
        return wrapped[0] - bare[0]

    def parts(duration: float) -> tuple[float, float, int]:
        """ns of a run spent outside the timed calls, ns inside solve_maze's steps, and its steps."""
        controller = make("solve_maze", {})
        controller.step = timed(controller.step, "solve_maze")
        inside.update(solve_maze=0, others=0)
        start = perf_counter_ns()
        result = run(load_world("maze"), [RobotSetup(with_noise(CTBOT, DEFAULT_NOISE), controller)], duration)
        total = perf_counter_ns() - start
        cost = timing_cost()
        return total - inside["solve_maze"] - inside["others"] - 4 * cost * len(result), inside["solve_maze"] - cost * len(result), len(result) - 1

    originals = (World.read_all, World.step, DefaultOdometry.update_into)
    World.read_all, World.step, DefaultOdometry.update_into = (timed(call) for call in originals)
    try:
        best = {"glue": float("inf"), "solve_maze": float("inf")}
        for _ in range(repeats):
            (long_ns, long_maze, long_steps), (short_ns, short_maze, short_steps) = parts(steps * 0.01), parts(0.01)
            best["glue"] = min(best["glue"], (long_ns - short_ns) / (long_steps - short_steps) / 1000)
            best["solve_maze"] = min(best["solve_maze"], (long_maze - short_maze) / (long_steps - short_steps) / 1000)
        return best
    finally:
        World.read_all, World.step, DefaultOdometry.update_into = originals


_IRSIM_LIDAR = '''
import os, sys, tempfile, time
os.environ.setdefault("MPLBACKEND", "Agg")
steps = int(sys.argv[1])
world = """
world:
  height: 3.12
  width: 3.12
  step_time: 0.1
  collision_mode: stop
robot:
  - kinematics: {name: diff}
    shape: {name: circle, radius: 0.06}
    state: [1.56, 0.9, 0]
    sensors:
      - name: lidar2d
        range_min: 0
        range_max: 0.8
        angle_range: 0.5
        number: 2
obstacle:
  - shape: {name: rectangle, length: 3.12, width: 0.12}
    state: [1.56, 0.0, 0]
  - shape: {name: rectangle, length: 3.12, width: 0.12}
    state: [1.56, 3.12, 0]
  - shape: {name: rectangle, length: 0.12, width: 3.12}
    state: [0.0, 1.56, 0]
  - shape: {name: rectangle, length: 0.12, width: 3.12}
    state: [3.12, 1.56, 0]
  - shape: {name: rectangle, length: 0.12, width: 1.2}
    state: [2.5, 1.4, 0]
"""
with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
    f.write(world)
import irsim
import numpy as np

env = irsim.make(f.name, display=False)
action = np.array([[0.15], [0.3]])
env.step(action)
best = 0.0
for _ in range(3):
    env.reset()
    start = time.perf_counter()
    for _ in range(steps):
        env.step(action)
    best = max(best, steps / (time.perf_counter() - start))
print(best * 0.1)  # simulated seconds per wall second at the world's step_time
'''


SQUARE_BOXES = ((1.56, 0.0, 3.12, 0.12), (1.56, 3.12, 3.12, 0.12), (0.0, 1.56, 0.12, 3.12), (3.12, 1.56, 0.12, 3.12), (2.5, 1.4, 0.12, 1.2))
"""The walled square of `_IRSIM_LIDAR` (centre x, y, length along x, width along y; m)."""


def _box(x: float, y: float, length: float, width: float) -> Wall:
    hx, hy = length / 2, width / 2
    return Wall(((x - hx, y - hy), (x + hx, y - hy), (x + hx, y + hy), (x - hx, y + hy)))


def _peer_python(variable: str, default: str) -> str:
    """The python of a peer simulator's own venv: the one `variable` names, else `default`."""
    import os

    return os.environ.get(variable, default)


def irsim_sim_seconds(steps: int) -> float:
    """Simulated seconds per wall second of IR-SIM's differential-drive robot with a 2-beam lidar
    (0.8 m) at dt 0.1 s, a constant action, no display or recording, in `SQUARE_BOXES` (best of
    3, in a child process); nan where IR-SIM is not installed. IR-SIM is a peer to compare with,
    not a dependency: install it (`pip install ir-sim`) into a venv of its own and name its python
    in CTSIM_IRSIM_PYTHON (default: this python)."""
    import subprocess
    import sys

    try:
        done = subprocess.run([_peer_python("CTSIM_IRSIM_PYTHON", sys.executable), "-c", _IRSIM_LIDAR, str(steps)], capture_output=True, text=True, timeout=600)
        return float(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else float("nan")
    except (OSError, ValueError, IndexError, subprocess.TimeoutExpired):
        return float("nan")


def two_ir_sim_seconds(steps: int) -> float:
    """IR-SIM's work in ctsim: one c't-Bot with its two IR range sensors (0.8 m) and nothing else
    (no mouse, floor or light sensors), read every step, at dt 0.1 s with a constant command in
    `SQUARE_BOXES`, no recording; simulated seconds per wall second."""
    ranged = CTBOT.with_changes(name="two_ir", mouse=None, line=(), border=(), light=())
    world = World(WorldSpec("square", (0.0, 0.0, 3.12, 3.12), walls=tuple(_box(*b) for b in SQUARE_BOXES)), dt=0.1)
    world.add_robot(ranged, (1.56, 0.9, 0.0))
    return 0.1 * _steps_per_second(world, steps, np.array([[60.0, 120.0]]))


def irsim_like_for_like(steps: int, rounds: int = 3) -> float:
    """`two_ir_sim_seconds` over `irsim_sim_seconds`, each the best of `rounds` alternating runs;
    nan where IR-SIM is not installed."""
    ours, theirs = 0.0, 0.0
    for _ in range(rounds):
        ours = max(ours, two_ir_sim_seconds(steps))
        theirs = max(theirs, irsim_sim_seconds(steps))  # (max(0, nan) stays 0: IR-SIM absent)
    return ours / theirs if theirs > 0.0 else float("nan")


_ENKI = """
import json, sys, time
import pyenki
boxes, rooms, count, steps, dt = json.loads(sys.argv[1])
side = 100.0 * (0.48 * rooms + 0.24)  # cm
world = pyenki.World(side, side)
for x, y, length, width in boxes:
    wall = pyenki.RectangularObject(100.0 * length, 100.0 * width, 5.0, -1.0, pyenki.Color(0.5, 0.5, 0.5))
    wall.pos = (100.0 * x, 100.0 * y)
    world.addObject(wall)
thymios = []
for k in range(count):
    thymio = pyenki.Thymio2()
    thymio.pos = (100.0 * (0.36 + 0.48 * (k % rooms)), 100.0 * (0.36 + 0.48 * (k // rooms)))
    thymio.angle = 1.5708
    thymio.leftSpeed, thymio.rightSpeed = 10.0, 9.0
    world.addObject(thymio)
    thymios.append(thymio)


def advance(n):
    for _ in range(n):
        world.step(dt, 1)
        for thymio in thymios:
            thymio.proximitySensorValues, thymio.groundSensorValues


advance(min(steps, 200))
best = 0.0
for _ in range(3):
    start = time.perf_counter()
    advance(steps)
    best = max(best, steps / (time.perf_counter() - start))
print(best)
"""


def enki_steps_per_second(count: int, steps: int, dt: float = 0.01) -> float:
    """Steps per second of `count` Thymio IIs in Enki (Debian's python3-enki2, C++), each reading
    its 7 proximity and 2 ground sensors every step, in the walls of `generated_maze` (one robot
    per room, at the rooms' centres, in cm), best of 3 in a child process; nan where Enki is not
    installed (`apt-get install python3-enki2`; CTSIM_ENKI_PYTHON names its python, default the
    system's /usr/bin/python3)."""
    import json
    import math
    import subprocess

    rooms = max(2, math.ceil(math.sqrt(count)))
    boxes = [_bounds_box(wall) for wall in generated_maze(rooms).walls]
    arguments = json.dumps([boxes, rooms, count, steps, dt])
    try:
        done = subprocess.run([_peer_python("CTSIM_ENKI_PYTHON", "/usr/bin/python3"), "-c", _ENKI, arguments], capture_output=True, text=True, timeout=1200)
        return float(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else float("nan")
    except (OSError, ValueError, IndexError, subprocess.TimeoutExpired):
        return float("nan")


def _bounds_box(wall: Wall) -> tuple[float, float, float, float]:
    """A rectangular wall as (centre x, y, length along x, width along y)."""
    xs, ys = [v[0] for v in wall.vertices], [v[1] for v in wall.vertices]
    return ((min(xs) + max(xs)) / 2, (min(ys) + max(ys)) / 2, max(xs) - min(xs), max(ys) - min(ys))


def maze_crowd(count: int, steps: int, dt: float = 0.01) -> float:
    """`enki_steps_per_second`'s work in ctsim: `count` c't-Bots with every sensor (realistic
    noise), each read every step, one per room of `generated_maze` and driving gently."""
    import math

    rooms = max(2, math.ceil(math.sqrt(count)))
    world = World(generated_maze(rooms), dt=dt, floor_cell=0.01)
    robot = with_noise(CTBOT, DEFAULT_NOISE)
    for k in range(count):
        world.add_robot(robot, (0.36 + 0.48 * (k % rooms), 0.36 + 0.48 * (k // rooms), np.pi / 2))
    return _steps_per_second(world, steps, np.tile([200.0, 180.0], (count, 1)), repeats=1)


def maze_over_enki(count: int, steps: int, rounds: int = 3) -> float:
    """ctsim's `maze_crowd` over Enki's `enki_steps_per_second`, the best of `rounds` alternating
    runs of each (robot-steps per second alike)."""
    ours, theirs = 0.0, 0.0
    for _ in range(rounds):
        ours = max(ours, maze_crowd(count, steps))
        theirs = max(theirs, enki_steps_per_second(count, steps))
    return ours / theirs


def rerun_import() -> float:
    """Seconds to import rerun in a fresh process (what the first recording of a `ctsim run` pays)."""
    import subprocess
    import sys

    script = "import time; t = time.perf_counter(); import rerun; print(time.perf_counter() - t)"
    return min(float(subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout) for _ in range(3))


def many_ctbots(steps: int, count: int = 100) -> float:
    """`count` c't-Bots with every sensor in one open floor sized for them (a square grid, 0.3 m
    apart), each driving a wide circle, so that neighbours meet now and then."""
    side = int(np.ceil(np.sqrt(count)))
    spacing = 0.3
    # a coarse floor raster: the default 2 mm cells of a 10 m floor would take hundreds of MB
    world = World(WorldSpec("open", (0.0, 0.0, side * spacing, side * spacing)), floor_cell=0.01)
    for k in range(count):
        world.add_robot(CTBOT, ((k % side + 0.5) * spacing, (k // side + 0.5) * spacing, 0.0))
    commands = np.tile([150.0, 170.0], (count, 1))
    return _steps_per_second(world, steps, commands)


def _once(measure: Callable[[], Measured]) -> Callable[[], Measured]:
    """`measure`, run on the first call only: several lines print or divide by one figure."""
    value: list[Measured] = []

    def measured() -> Measured:
        if not value:
            value.append(measure())
        return value[0]

    return measured


def figures(scale: float):
    """(name, unit, thunk) for the world benchmarks."""
    yield "world_empty_1bot", "steps/s", lambda: empty_1bot(int(20000 * scale))
    yield "world_mecanum_4wheel", "steps/s", lambda: mecanum_4wheel(int(20000 * scale))
    world_step = _once(lambda: maze_ctbot(int(10000 * scale)))
    yield "world_maze_ctbot_all_sensors", "steps/s", world_step
    big_maze_step = _once(lambda: big_maze_ctbot(int(10000 * scale)))
    yield "world_big_maze_ctbot_all_sensors", "steps/s (934 walls)", big_maze_step
    yield "world_big_maze_over_maze", "(cost of a step among 934 walls / among the shipped maze's 22, same run)", lambda: world_step() / big_maze_step()
    steps = int(180_000 * scale)  # asked for: 30 simulated minutes (full), 6 (quick); solve_maze's runs end at the goal (~240 s)
    measured: dict[str, float] = {}

    def once(kind: str) -> float:
        """The best of five of each kind ('world', 'run', 'recording'), interleaved and each as
        many steps as a run: a run takes seconds, and the machine's speed drifts over seconds
        (a burst of the bare world step, as `world_maze_ctbot_all_sensors`, catches its fastest
        spell; a run its average). On a 2-core VM whose speed drifted by a third over tens of
        seconds, three of each once left every plain run in a slow spell (recording ratio 0.99,
        against 0.71-0.79 in the runs around it). rerun is imported before them, so that all
        recorded runs are alike: its import, once per process, is `rerun_import_s`."""
        if not measured:
            import rerun  # noqa: F401

            for _ in range(5):
                for key, measure in (("world", lambda: maze_ctbot(steps, repeats=1, noise=DEFAULT_NOISE)), ("run", lambda: maze_run(steps, False)),
                                     ("recording", lambda: maze_run(steps, True))):  # fmt: skip
                    measured[key] = max(measured.get(key, 0.0), measure())
        return measured[kind]

    yield "run_maze_solve", "steps/s", lambda: once("run")
    yield "world_maze_ctbot_beside_runs", "steps/s (the bare world step as long as a run, interleaved with the runs)", lambda: once("world")
    # (5,000 steps in --quick too: the noise's slip takes the robot along another path through the maze, so
    # that a thousand steps of each compare different stretches; seen: 1.28 and 1.39 at 1,000, 1.08-1.20 at 5,000)
    yield "world_maze_noise_over_exact", "(cost of a world step with realistic noise / exact, interleaved; bar <= 1.25)", lambda: noise_over_exact(5000)
    yield "run_maze_solve_over_world_step", "(whole run / bare world step beside it, realistic noise on both; bar >= 0.5)", lambda: once("run") / once("world")
    run_part = _once(lambda: run_parts(steps))
    yield "run_loop_glue_us", "µs a step (the run loop's own work beside the world step, solve_maze and the default estimators, timed from outside; bar <= 5)", \
        lambda: run_part()["glue"]
    yield "solve_maze_step_us", "µs a step (solve_maze's own work in that run, its `step` timed from outside; bar <= 10)", lambda: run_part()["solve_maze"]
    yield "run_maze_solve_recording", "steps/s", lambda: once("recording")
    yield "run_maze_solve_recording_ratio", "(recording / run, same run; bar >= 0.8)", lambda: once("recording") / once("run")
    yield "run_over_irsim_like_for_like", "(simulated s per wall s: one robot, two range sensors, dt 0.1, constant command, no recording, ctsim over IR-SIM; nan: IR-SIM not installed)", \
        lambda: irsim_like_for_like(max(int(20_000 * scale), 1000))
    yield "rerun_import_s", "s (once per process, before the first recording; own process)", rerun_import
    crowds: dict[int, float] = {}

    def crowd(count: int) -> float:
        if count not in crowds:
            crowds[count] = many_ctbots(max(int(30_000 * scale) // count, 10), count)
        return crowds[count]

    for count in (1, 100, 1000):
        yield (f"world_maze_over_enki_{count}", f"(robot-steps/s: {count} c't-Bot(s) with every sensor over Enki's Thymio II with 7 proximity and 2 ground sensors, "
               "walled maze, alternating runs; bar >= 2; nan: python3-enki2 not installed)", lambda count=count: maze_over_enki(count, max(int(20_000 * scale) // count, 20)))
    yield "world_100_ctbots", "steps/s", lambda: crowd(100)
    yield "world_1000_ctbots", "steps/s", lambda: crowd(1000)
    yield "world_ctbots_cost_1000_over_10", "(cost per robot-step at 1,000 / at 10 robots, same run; bar <= 1.5)", lambda: 10 * crowd(10) / (1000 * crowd(1000))
