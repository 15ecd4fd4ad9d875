"""One visual language for the rerun recording, the PNG figures and the pygame window.

Truth is always the same green and each odometry estimate always the same colour (by name, so
"mouse" is purple whatever else ran); the map's elements share their colours too. Colours are
0-255 RGB tuples; `hex_colour` and `unit` convert for matplotlib.
"""

from __future__ import annotations

RGB = tuple[int, int, int]

TRUTH: RGB = (34, 150, 64)
ESTIMATES: dict[str, RGB] = {
    "encoders": (230, 120, 20),
    "firmware": (40, 104, 220),
    "mouse": (170, 60, 190),
    "fused": (20, 160, 160),
    "fused_blend": (200, 40, 60),
    "arc": (140, 100, 40),
    "localiser": (200, 20, 110),
}
SPARE: tuple[RGB, ...] = ((120, 120, 120), (230, 170, 0), (90, 60, 160))
"""Colours of estimates without one of their own, in order of appearance."""

WALL: RGB = (30, 32, 40)
WALL_EDGE: RGB = (120, 124, 136)
"""Walls are near black with a light edge: they stand out on c't-Sim's mid-grey floor (#606060)
as on a white one."""
BACKGROUND: RGB = (210, 210, 214)
"""Around the map (rerun view, window)."""
HOLE: RGB = (0, 0, 0)
HOLE_EDGE: RGB = (200, 40, 40)
"""Holes are black as the floor sensors see them, edged in red: a wall is near black too."""
GOAL: RGB = (120, 220, 140)
GOAL_EDGE: RGB = (30, 140, 60)
CAN: RGB = (200, 120, 42)
"""Movable cans (c't-Sim's 30 mm objects), drawn at their start."""
LIGHT: RGB = (255, 205, 30)
LIGHT_EDGE: RGB = (150, 110, 0)
START: RGB = (60, 130, 240)
RAY: RGB = (225, 40, 40)
HIT: RGB = (255, 90, 0)
ROBOT_EDGE: RGB = (20, 20, 20)
WHEEL: RGB = (40, 40, 40)
"""Wheels of a general chassis, drawn along their rolling direction with the head at the front."""
FAULT: RGB = (225, 30, 30)
"""A wheel that failed (locked, rolling free, steering frozen)."""
ICR: RGB = (230, 60, 200)
"""The instantaneous centre of rotation of a robot's motion."""
CONTESTANTS: tuple[RGB, RGB] = ((214, 48, 49), (37, 99, 235))
"""The two bots of a contest game: red from start slot 1, blue from slot 2 (c't-Sim's start tiles)."""
ROBOTS: tuple[RGB, ...] = ((214, 48, 49), (240, 200, 20), (250, 250, 250), (255, 140, 190), (140, 80, 30), (150, 230, 80))
"""Each robot's own colour where several share a run (its outline, name, ground-truth trail), in
the order they were added: red, yellow, white, pink, brown, light green; none is an estimate's,
all stand out on a grey floor."""
NEUTRAL: RGB = (90, 110, 140)
"""Marks that belong to no estimate or robot."""
KEY_NOTE: RGB = (20, 20, 20)
"""An entry of the recording's colour key that is no estimate's or robot's (the error plots' thin
3σ bands): dark, to read as a thin line beside the map."""
KEY_EDGE: RGB = (40, 40, 40)
"""The rim round each swatch of the recording's colour key: a light robot colour (white, yellow)
would fade into the light grey beside the map without it."""
LABEL_TEXT: RGB = (255, 255, 255)
"""The text of the recording's labels (its colour key, the robots' names on the map), as rerun
writes labels of its own: light on its grey label box. Each entry's colour is its swatch's, each
robot's its outline's; text in those colours was hard to read there (a red name, a white one)."""
OUTCOMES: dict[str, RGB] = {"goal reached": GOAL_EDGE, "time limit": NEUTRAL, "fell": (70, 70, 70), "error": FAULT, "controller done": START}
"""How a sweep's runs ended (`sim.experiments.report.OUTCOMES`): the goal's green, grey-blue for
running out of time, a hole's near black, a fault's red."""
SCALE_BAR: RGB = (20, 20, 20)
CHANNELS: tuple[RGB, ...] = ((31, 119, 180), (214, 39, 40), (44, 160, 44), (148, 103, 189), (140, 86, 75), (23, 190, 207))
"""Colours of a sensor's channels (left, right, ...)."""


def estimate_colour(name: str, others: list[str] | tuple[str, ...] = ()) -> RGB:
    """The colour of estimate `name`; unnamed ones take spare colours by their place in `others`."""
    if name in ESTIMATES:
        return ESTIMATES[name]
    unknown = [n for n in others if n not in ESTIMATES]
    return SPARE[unknown.index(name) % len(SPARE)] if name in unknown else SPARE[0]


def pale(rgb: RGB, strength: float = 0.35) -> RGB:
    """`rgb` mixed with white (`strength` 1: as is, 0: white): an estimate's every-sample trace
    and its box fill, opaque so that overlapping traces never blend into a colour of no estimate."""
    return tuple(round(255 - strength * (255 - c)) for c in rgb)


def robot_colours(names: list[str] | tuple[str, ...]) -> dict[str, RGB]:
    """Robot name -> its own colour (`ROBOTS`, in order) when there are several; none for a lone
    robot, whose truth stays TRUTH green."""
    return {name: ROBOTS[k % len(ROBOTS)] for k, name in enumerate(names)} if len(names) > 1 else {}


def unit(rgb: RGB) -> tuple[float, float, float]:
    """0-255 to the 0-1 floats matplotlib takes."""
    return tuple(c / 255 for c in rgb)


def hex_colour(rgb: RGB) -> str:
    """'#rrggbb' of an RGB tuple."""
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def from_unit(rgb: tuple[float, float, float]) -> RGB:
    """A world file's 0-1 colour as 0-255."""
    return tuple(int(round(255 * c)) for c in rgb)
