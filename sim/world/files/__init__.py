"""World files: load a `.toml` (ctsim's own format) or a c't-Sim parcours `.xml` into a WorldSpec.

    load_world("maze")                  # a shipped world, worlds/maze.toml
    load_world("my_track.toml")         # a path
    check_world("my_track.toml")        # -> warnings; raises WorldFileError for errors

Every user mistake raises `WorldFileError(path, line, problem)`; `str()` of it reads `file:line: problem`.
"""

from __future__ import annotations

import difflib
import math
import os
from pathlib import Path

import sim
from sim.world.spec import WorldFileError, WorldSpec

from .geometry import Budget, Near, inside
from .parcours import load_parcours
from .toml_format import load_toml

__all__ = ["WorldFileError", "check_world", "load_world", "shipped_worlds", "world_warnings", "worlds_dir"]

_LOADERS = {".toml": load_toml, ".xml": load_parcours}
ROBOT_RADIUS = 0.06  # m, half a c't-Bot's width: a start closer than this to a wall touches it
COMMON_ROBOTS = 2  # c't-Sim's worlds give slots 1 and 2: a world is commonly run with two bots


def worlds_dir() -> Path:
    """The repository's `worlds/` folder."""
    return Path(sim.__file__).resolve().parent.parent / "worlds"


def shipped_worlds() -> dict[str, Path]:
    """Shipped worlds by name (file stem), sorted."""
    folder = worlds_dir()
    found = sorted(folder.glob("*.toml")) if folder.is_dir() else []
    return {p.stem: p for p in found}


def _resolve(source: str | Path) -> Path:
    """A path as given, or the shipped world of that bare name (a folder of that name here, such as
    a run's output folder `maze/`, is no world file and does not hide it). A name written with a
    directory part (`./maze`, `maze/`) is that path: pathlib drops a leading `./`, so the text is
    asked, not the Path."""
    path = Path(source)
    if path.suffix or os.path.dirname(source) or path.is_file():
        return path
    worlds = shipped_worlds()
    if str(source) in worlds:
        return worlds[str(source)]
    close = difflib.get_close_matches(str(source), worlds, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise WorldFileError(source, None, f"no such world file or shipped world; {hint}shipped: {', '.join(worlds) or 'none'}")


def load_world(source: str | Path, pillars: str = "cell") -> WorldSpec:
    """Load a world from a `.toml` or c't-Sim `.xml` file, or a shipped world by bare name.
    `pillars`: how a c't-Sim parcours' lamp pillars stand, 'cell' (wall blocks) or 'cylinder'
    (c't-Sim's own 0.1 m cylinders, as the bridge loads them; `sim.world.files.grid`)."""
    path = _resolve(source)
    if path.is_dir():  # (named as written: `./maze` is not the shipped maze)
        raise WorldFileError(str(source), None, "is a folder, not a world file; give a .toml or .xml file or a shipped world's name (`ctsim worlds`)")
    if not path.suffix and not path.exists():
        raise WorldFileError(str(source), None, "no such file")
    loader = _LOADERS.get(path.suffix.lower())
    if loader is None:
        raise WorldFileError(path, None, f"unknown world file type '{path.suffix}'; expected .toml or .xml")
    if not path.exists():
        raise WorldFileError(path, None, "no such file")
    world = load_parcours(path, pillars) if loader is load_parcours else loader(path)
    if not world.start_order():
        raise WorldFileError(path, None, "the world has no start pose (room for 0 robots): add a start tile (0, 1, 2) or a [[start]]")
    return world


def check_world(source: str | Path) -> list[str]:
    """Load a world and return its warnings (`world_warnings`); errors raise WorldFileError as in
    `load_world`."""
    return world_warnings(load_world(source))


CHECK_BUDGET = 5_000_000
"""Most (point, polygon) pairs and polygon corners `world_warnings` looks at: the checks of a 500 x
500 grid of walls and starts look at about 3 million; beyond the budget they stop and say so."""


def world_warnings(world: WorldSpec, budget: int = CHECK_BUDGET) -> list[str]:
    """What a loader noted (`WorldSpec.notes`), then warnings from cheap geometric checks: starts
    in or against walls, inside movables, over holes or outside the world; clashing start slots;
    goals inside walls or outside the world, movables inside walls. Walls, holes and movables are
    binned (`geometry.Near`), and the work is bounded by `budget` pairs."""
    warnings = list(world.notes)
    spent = Budget(budget)
    walls = Near([w.vertices for w in world.walls], spent)
    holes = Near([h.vertices for h in world.holes], spent)
    cans = Near([_square(m.position, m.radius) for m in world.movables], spent)
    xmin, ymin, xmax, ymax = world.bounds
    slots: dict[int, int] = {}
    for i, start in enumerate(world.starts, 1):
        p = (start.x, start.y)
        label = f"start #{i} (slot {start.slot}) at ({start.x:.3f}, {start.y:.3f})"
        slots[start.slot] = slots.get(start.slot, 0) + 1
        near = [world.walls[k].vertices for k in walls.near(p, ROBOT_RADIUS)]
        if any(inside(p, wall) for wall in near):
            warnings.append(f"{label} is inside a wall")
        elif (gap := _distance_to_walls(p, near)) < ROBOT_RADIUS:
            warnings.append(f"{label} is {gap:.3f} m from a wall, closer than a c't-Bot's radius ({ROBOT_RADIUS} m)")
        for k in cans.near(p, ROBOT_RADIUS):
            can = world.movables[k]
            if (gap := math.dist(p, can.position) - can.radius) < ROBOT_RADIUS:
                where = "inside" if gap < 0 else f"{gap:.3f} m from"
                warnings.append(f"{label} is {where} movable #{k + 1}, closer than a c't-Bot's radius ({ROBOT_RADIUS} m): "
                                "the robot's body overlaps it and shoves it away at the start")
                break
        if any(inside(p, world.holes[k].vertices) for k in holes.near(p, 0.0)):
            warnings.append(f"{label} is over a hole")
        if not (xmin < start.x < xmax and ymin < start.y < ymax):
            warnings.append(f"{label} is outside the world's bounds" + (" (over the abyss)" if world.outside_is_hole else ""))
    for slot, count in sorted(slots.items()):
        if count > 1:
            warnings.append(f"{count} starts share slot {slot}; the last one is used")
    warnings += _crowded(world.start_order(), spent)
    for i, goal in enumerate(world.goals, 1):
        centre = tuple(sum(c) / len(goal.vertices) for c in zip(*goal.vertices))
        if any(inside(centre, world.walls[k].vertices) for k in walls.near(centre, 0.0)):
            warnings.append(f"goal #{i} is inside a wall")
        if not (xmin <= centre[0] <= xmax and ymin <= centre[1] <= ymax):
            warnings.append(f"goal #{i} at ({centre[0]:.3f}, {centre[1]:.3f}) is outside the world's bounds "
                            f"[{xmin:g}, {ymin:g}, {xmax:g}, {ymax:g}]: no robot can reach it")
        if goal.slot and goal.slot not in slots:
            warnings.append(f"goal #{i} is for the robot from start slot {goal.slot}, but no start has that slot")
    for i, can in enumerate(world.movables, 1):
        if any(inside(can.position, world.walls[k].vertices) for k in walls.near(can.position, 0.0)):
            warnings.append(f"movable #{i} at ({can.position[0]:.3f}, {can.position[1]:.3f}) is inside a wall")
    if spent.exhausted:
        warnings.append(f"the checks stopped after looking at {budget:,} pairs of points and shapes: this world has more "
                        "starts, walls, holes and movables than `check` looks through; the warnings above are the first found")
    return warnings


def _square(centre: tuple[float, float], radius: float) -> tuple[tuple[float, float], ...]:
    """The box around a circle (for binning movables)."""
    (x, y), r = centre, radius
    return ((x - r, y - r), (x + r, y - r), (x + r, y + r), (x - r, y + r))


def _crowded(starts: list, budget: Budget, most: int = 10) -> list[str]:
    """Warnings for start slots closer than two c't-Bots need (the first `most`): robots started
    there overlap, and a run that uses both is refused. Sorted by x, each start is compared only
    with those less than that far to its left (within `budget`)."""
    apart = 2 * ROBOT_RADIUS
    found: list[str] = []
    order = sorted(range(len(starts)), key=lambda k: starts[k].x)
    for n, j in enumerate(order):
        for i in (order[k] for k in range(n - 1, -1, -1)):
            if starts[j].x - starts[i].x >= apart or len(found) >= most or not budget.spend(1):
                break
            gap = math.hypot(starts[j].x - starts[i].x, starts[j].y - starts[i].y)
            if gap < apart:
                found.append(f"the starts of slots {starts[i].slot} and {starts[j].slot} are {gap:.3f} m apart, closer than two c't-Bots "
                             f"need ({apart:.2f} m): robots started there overlap, and a run with both is refused")
    return found


def _distance_to_walls(p: tuple[float, float], walls: list[tuple[tuple[float, float], ...]]) -> float:
    """Distance from p to the nearest wall edge (inf without walls)."""
    best = math.inf
    for wall in walls:
        for a, b in zip(wall, wall[1:] + wall[:1]):
            ax, ay, bx, by = *a, *b
            dx, dy = bx - ax, by - ay
            t = max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / (dx * dx + dy * dy or 1.0)))
            best = min(best, math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy))
    return best


def room_warning(world: WorldSpec, robots: int = COMMON_ROBOTS) -> str | None:
    """A warning when the world has start slots for fewer than `robots` robots (each robot needs
    a slot of its own: a robot beyond them is refused, where c't-Sim puts it on top of another)."""
    room = len(world.start_order())
    if room >= robots:
        return None
    return (
        f"room for {room} robot(s) only: the world has {room} start slot(s) and a robot beyond them is refused "
        f"(c't-Sim would put it on top of another); add starts (slot 1, 2, ...) to run {robots} robots"
    )
