"""World files: load a `.toml` (ctsim's own format) or a c't-Sim parcours `.xml` into a WorldSpec.

    load_world("maze")                  # a shipped world, worlds/maze.toml
    load_world("my_track.toml")         # a path
    check_world("my_track.toml")        # -> warnings; raises WorldFileError for errors

Every user mistake raises `WorldFileError(path, line, problem)`; `str()` of it reads `file:line: problem`.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path

import sim
from sim.world.spec import WorldFileError, WorldSpec

from .geometry import inside
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
    """A path as given, or the shipped world of that bare name."""
    path = Path(source)
    if path.suffix or path.parent != Path(".") or path.exists():
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
    loader = _LOADERS.get(path.suffix.lower())
    if loader is None:
        raise WorldFileError(path, None, f"unknown world file type '{path.suffix}'; expected .toml or .xml")
    if not path.is_file():
        raise WorldFileError(path, None, "no such file")
    world = load_parcours(path, pillars) if loader is load_parcours else loader(path)
    if not world.start_order():
        raise WorldFileError(path, None, "the world has no start pose (room for 0 robots): add a start tile (0, 1, 2) or a [[start]]")
    return world


def check_world(source: str | Path) -> list[str]:
    """Load a world and return its warnings (`world_warnings`); errors raise WorldFileError as in
    `load_world`."""
    return world_warnings(load_world(source))


def world_warnings(world: WorldSpec) -> list[str]:
    """Warnings from cheap geometric checks: starts in or against walls, over holes or outside the
    world; clashing start slots; goals and cans inside walls."""
    warnings = []
    solids = [w.vertices for w in world.walls]
    holes = [h.vertices for h in world.holes]
    xmin, ymin, xmax, ymax = world.bounds
    slots: dict[int, int] = {}
    for i, start in enumerate(world.starts, 1):
        p = (start.x, start.y)
        label = f"start #{i} (slot {start.slot}) at ({start.x:.3f}, {start.y:.3f})"
        slots[start.slot] = slots.get(start.slot, 0) + 1
        if any(inside(p, wall) for wall in solids):
            warnings.append(f"{label} is inside a wall")
        elif (gap := _distance_to_walls(p, solids)) < ROBOT_RADIUS:
            warnings.append(f"{label} is {gap:.3f} m from a wall, closer than a c't-Bot's radius ({ROBOT_RADIUS} m)")
        if any(inside(p, hole) for hole in holes):
            warnings.append(f"{label} is over a hole")
        if not (xmin < start.x < xmax and ymin < start.y < ymax):
            warnings.append(f"{label} is outside the world's bounds" + (" (over the abyss)" if world.outside_is_hole else ""))
    for slot, count in sorted(slots.items()):
        if count > 1:
            warnings.append(f"{count} starts share slot {slot}; the last one is used")
    warnings += _crowded(world.start_order())
    for i, goal in enumerate(world.goals, 1):
        centre = tuple(sum(c) / len(goal.vertices) for c in zip(*goal.vertices))
        if any(inside(centre, wall) for wall in solids):
            warnings.append(f"goal #{i} is inside a wall")
        if goal.slot and goal.slot not in slots:
            warnings.append(f"goal #{i} is for the robot from start slot {goal.slot}, but no start has that slot")
    for i, can in enumerate(world.movables, 1):
        if any(inside(can.position, wall) for wall in solids):
            warnings.append(f"movable #{i} at ({can.position[0]:.3f}, {can.position[1]:.3f}) is inside a wall")
    return warnings


def _crowded(starts: list, most: int = 10) -> list[str]:
    """Warnings for start slots closer than two c't-Bots need (the first `most`): robots started
    there overlap, and a run that uses both is refused. Sorted by x, each start is compared only
    with those less than that far to its left."""
    apart = 2 * ROBOT_RADIUS
    found: list[str] = []
    order = sorted(range(len(starts)), key=lambda k: starts[k].x)
    for n, j in enumerate(order):
        for i in reversed(order[:n]):
            if starts[j].x - starts[i].x >= apart or len(found) >= most:
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
