"""Issue 3: line and border sensors read the floor colour (c't-Sim's CNY70 codes, holes black), and
light sensors the distance to the nearest light inside their cone."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.ctbot import CTBOT
from sim.world import World
from sim.world.sensors import cny70_value, ldr_value
from sim.world.spec import (
    BLACK,
    WHITE,
    FloorLine,
    FloorRegion,
    Hole,
    Light,
    WorldSpec,
    box,
)


def hexcolour(code: str) -> tuple[float, float, float]:
    return tuple(int(code[i : i + 2], 16) / 255 for i in (1, 3, 5))


def floor_readings(**world) -> tuple[np.ndarray, np.ndarray]:
    """(line, border) of a c't-Bot at the origin facing +x in a world with the given floor items."""
    w = World(WorldSpec("floor", (-1, -1, 1, 1), **world))
    w.add_robot(CTBOT, (0.0, 0.0, 0.0))
    r = w.read_all()[0]
    return r.line, r.border


def test_plain_floor_reads_637():
    """c't-Sim's normal floor #606060 reads 637 on all four CNY70 sensors."""
    line, border = floor_readings()
    assert list(line) == [637, 637] and list(border) == [637, 637]


@pytest.mark.parametrize(("colour", "value"), [(WHITE, 0), (BLACK, 1023), (hexcolour("#993030"), 0x2B2), (hexcolour("#000099"), 0x332)])
def test_floor_colours_give_ctsim_codes(colour, value):
    """White 0, black 1023, and the start pads' colours the firmware's codes 0x2B2 and 0x332."""
    line, border = floor_readings(floor=(FloorRegion(box(-0.2, -0.2, 0.2, 0.2), colour),))
    assert list(line) == [value] * 2 and list(border) == [value] * 2


def test_goal_colour_reads_the_firmware_goal_code():
    """The goal colour #66FF00 reads GROUND_GOAL 0x221 = 545: 545.6 truncated, as c't-Sim does
    (it also truncates #606060's 637.9 to 637)."""
    line, _ = floor_readings(floor=(FloorRegion(box(-0.2, -0.2, 0.2, 0.2), hexcolour("#66FF00")),))
    assert list(line) == [0x221, 0x221]


def test_a_black_line_under_one_sensor():
    """A 24 mm black line along x under the left line sensor only (y = +4 mm, line from y = 0 to
    24 mm): the left sensor reads 1023, the right one the plain floor."""
    line, border = floor_readings(lines=(FloorLine(((-0.5, 0.012), (0.5, 0.012)), width=0.024),))
    assert list(line) == [1023, 637]
    assert list(border) == [637, 637]  # the border sensors sit at y = +-36 mm, beside the line


def test_border_sensors_see_a_hole_ahead_before_the_wheels_reach_it():
    """A hole starting 30 mm ahead of the axle: the border sensors (38.4 mm ahead, 14 mm up) see it
    with all five rays of their sideways fan (1023) and four of the fan along the heading (the
    one 40 degrees back meets the floor at 38.4 - 11.7 mm: int((4 + 0.6235) * 1023 / 5) = 945),
    so they read (1023 + 945) // 2 = 984; the line sensors (9 mm ahead) the floor, and the robot
    has not fallen."""
    w = World(WorldSpec("hole", (-1, -1, 1, 1), holes=(Hole(box(0.03, -0.3, 0.3, 0.3)),)))
    robot = w.add_robot(CTBOT, (0.0, 0.0, 0.0))
    r = w.read_all()[0]
    assert list(r.border) == [984, 984] and list(r.line) == [637, 637]
    assert not robot.fallen


def test_cny70_value_function():
    """The transfer function: absorption 1 - mean(RGB) scaled to 0..1023 and truncated."""
    assert list(cny70_value(np.array([WHITE, BLACK, hexcolour("#606060")]))) == [0, 1023, 637]


LAMP = Light((0.8, 0.0), height=0.5)


def light_readings(pose, lights) -> np.ndarray:
    w = World(WorldSpec("lights", (-2, -2, 2, 2), lights=tuple(lights)))
    w.add_robot(CTBOT, pose)
    return w.read_all()[0].light


def surface_value(sensor, lamp: Light, pose=(0.0, 0.0, 0.0)) -> int:
    """c't-Sim's darkness: (distance from the sensor, 7.5 cm up, to the lamp sphere's surface) / 1 m
    x 1023, truncated."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    sx = pose[0] + c * sensor.position[0] - s * sensor.position[1]
    sy = pose[1] + s * sensor.position[0] + c * sensor.position[1]
    d = math.sqrt((lamp.position[0] - sx) ** 2 + (lamp.position[1] - sy) ** 2 + (lamp.height - 0.075) ** 2) - lamp.radius
    return math.floor(min(d, 1.0) * 1023)


def test_light_ahead_reads_the_distance_to_the_lamp_surface():
    """A lamp 0.8 m ahead and 0.5 m up: each LDR reads 1023 x distance to the 7 cm sphere."""
    values = light_readings((0.0, 0.0, 0.0), [LAMP])
    assert list(values) == [surface_value(sensor, LAMP) for sensor in CTBOT.light]


def test_a_lamp_50_degrees_off_axis_reads_599_as_in_ctsim():
    """c't-Sim's 90 deg is a half-angle: a lamp 0.5 m away horizontally, 50 deg to the left of the
    left sensor's axis, is seen: sqrt(0.5^2 + 0.425^2) - 0.07 = 0.5862 m -> 599 (ctsim used to
    read 1023 with a +-45 deg cone)."""
    sensor = CTBOT.light[0]
    angle = math.radians(50)
    lamp = Light((sensor.position[0] + 0.5 * math.cos(angle), sensor.position[1] + 0.5 * math.sin(angle)))
    values = light_readings((0.0, 0.0, 0.0), [lamp])
    assert values[0] == 599 == surface_value(sensor, lamp)


def test_the_nearest_lamp_in_the_half_space_ahead_counts():
    """Of lamps ahead (even 80 deg aside) the nearest sets the value; lamps behind are ignored;
    no light at all reads 1023."""
    near = Light((0.4, 0.1), height=0.3)
    behind = Light((-0.2, 0.0), height=0.1)
    aside = Light((0.1, 0.6), height=0.1)  # 80 deg off the heading: inside c't-Sim's half-space
    values = light_readings((0.0, 0.0, 0.0), [LAMP, near, behind, aside])
    for k, sensor in enumerate(CTBOT.light):
        assert values[k] == min(surface_value(sensor, lamp) for lamp in (LAMP, near, aside))
    assert list(light_readings((0.0, 0.0, 0.0), [])) == [1023, 1023]
    assert list(light_readings((0.0, 0.0, 0.0), [behind])) == [1023, 1023]
    assert list(light_readings((0.0, 0.0, math.pi), [LAMP])) == [1023, 1023]


def test_a_far_light_saturates():
    """A lamp farther than the sensor's reach (1 m) reads 1023, like none."""
    assert list(light_readings((0.0, 0.0, 0.0), [Light((1.5, 0.0), 0.5)])) == [1023, 1023]


def test_ldr_value_truncates():
    assert list(ldr_value(np.array([0.5862, 2.0, np.inf]))) == [599, 1023, 1023]
