"""World benchmarks: steps per second of whole simulation steps (sensors, control, physics)."""

from __future__ import annotations

import time

import numpy as np

from bots.ctbot import CTBOT
from sim.world import World
from sim.world.files import load_world
from sim.world.spec import Start, WorldSpec


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


def maze_ctbot(steps: int) -> float:
    """One c't-Bot reading every sensor each step in the shipped maze, turning gently so that it
    meets walls (contacts, sliding and ray hits included)."""
    world = World(load_world("maze"))
    world.add_robot(CTBOT)
    return _steps_per_second(world, steps, np.array([[200.0, 180.0]]))


def maze_ctbot_recording(steps: int, repeats: int = 3) -> float:
    """`maze_ctbot` with the rerun recorder observing every step into a temporary .rrd, fed a
    RobotLog as the run loop does (readings and truth), closing the file included; best of
    `repeats` after a warm-up, like the others."""
    import tempfile
    from pathlib import Path

    from sim.run import RobotLog
    from sim.views.recording import Recorder

    world = World(load_world("maze"))
    robot = world.add_robot(CTBOT)
    commands = np.array([[200.0, 180.0]])

    def record(count: int) -> float:
        logs = [RobotLog(robot.name, CTBOT, "constant", {}, [], count)]
        with tempfile.TemporaryDirectory() as folder:
            recorder = Recorder(Path(folder) / "bench.rrd")
            recorder.on_start(world, logs)
            start = time.perf_counter()
            for _ in range(count):
                logs[0].append(world.read_all()[0], robot.pose, [])
                recorder.on_sample(world, logs)
                world.step(commands)
            recorder.close()
            return count / (time.perf_counter() - start)

    record(min(steps, 2000))
    return max(record(steps) for _ in range(repeats))


def many_ctbots(steps: int, count: int = 100) -> float:
    """`count` c't-Bots with every sensor in one open world, on a grid, each driving a circle."""
    side = int(np.ceil(np.sqrt(count)))
    world = World(load_world("empty"))
    xmin, ymin, xmax, ymax = world.spec.bounds
    xs = np.linspace(xmin + 0.2, xmax - 0.2, side)
    ys = np.linspace(ymin + 0.2, ymax - 0.2, side)
    for k in range(count):
        world.add_robot(CTBOT, (xs[k % side], ys[k // side], 0.0))
    commands = np.tile([150.0, 170.0], (count, 1))
    return _steps_per_second(world, steps, commands)


def figures(scale: float):
    """(name, unit, thunk) for the world benchmarks."""
    yield "world_empty_1bot", "steps/s", lambda: empty_1bot(int(20000 * scale))
    yield "world_mecanum_4wheel", "steps/s", lambda: mecanum_4wheel(int(20000 * scale))
    yield "world_maze_ctbot_all_sensors", "steps/s", lambda: maze_ctbot(int(10000 * scale))
    yield "world_maze_ctbot_recording", "steps/s", lambda: maze_ctbot_recording(int(10000 * scale))
    yield "world_100_ctbots", "steps/s", lambda: many_ctbots(int(300 * scale))
