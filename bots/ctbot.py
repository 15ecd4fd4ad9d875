"""The c't-Bot (c't magazine's educational robot) as c't-Sim models it.

Positions are from c't-Sim (ctsim-reference.md §2), converted from its frame (x right, y forward)
to ours (x forward, y left): (x_ct, y_ct) -> (y_ct, -x_ct).
"""

from __future__ import annotations

import math

from bots.spec import (
    EncoderSpec,
    FloorSensorSpec,
    IRSensorSpec,
    LightSensorSpec,
    MotorSpec,
    MouseSpec,
    RobotSpec,
)

CTBOT = RobotSpec(
    name="ctbot",
    wheel_diameter=0.0567,
    track_width=0.0972,
    body_radius=0.060,
    mass=0.6,
    skid=(-0.054, 0.0),
    motor=MotorSpec(max_wheel_speed=151 / 60 * 2 * math.pi, command_max=255),
    encoders=EncoderSpec(ticks_per_rev=60),
    mouse=MouseSpec(mount=(-0.015, 0.0), dpi=400),
    ir=(
        IRSensorSpec("ir_left", (0.0554, 0.036), 0.0, side="left"),
        IRSensorSpec("ir_right", (0.0554, -0.036), 0.0, side="right"),
    ),
    line=(
        FloorSensorSpec("line_left", (0.009, 0.004)),
        FloorSensorSpec("line_right", (0.009, -0.004)),
    ),
    border=(
        FloorSensorSpec("border_left", (0.0384, 0.036), height=0.014),
        FloorSensorSpec("border_right", (0.0384, -0.036), height=0.014),
    ),
    light=(
        LightSensorSpec("light_left", (0.048, 0.032)),
        LightSensorSpec("light_right", (0.048, -0.032)),
    ),
)
"""The c't-Bot: wheels 56.7 mm, track 97.2 mm, body radius 60 mm, 60-tick encoders, mouse 15 mm
behind the axle at 400 dpi, two IR, line, border and light sensors. The border sensors' height is
c't-Sim's: its bot stands 75 mm up to its centre on a floor 1 mm up and they sit 60 mm below the
centre (14 mm over the floor: their rays reach ±12 mm). c't-Sim's line sensors, 11 mm lower, see
±2.5 mm the same way; here they read one point (height 0), because averaging across the edge of the
start tile passes through GROUND_GOAL and would end a maze run at the start."""

ROBOTS = {"ctbot": CTBOT}
"""Robot descriptions by name, for the command line."""
