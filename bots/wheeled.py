"""Shipped robots on general chassis: an omni-3, a Mecanum-4, a car (Ackermann) and the OCP paper's
four-wheel-steered example vehicle, each with a body outline, motors, mice and two IR sensors."""

from __future__ import annotations

import math

from bots.chassis_spec import ChassisSpec
from bots.spec import IRSensorSpec, MouseSpec, RobotSpec, wheeled_robot
from sim.kinematics import chassis_presets


def _box(front: float, back: float, half_width: float) -> tuple[tuple[float, float], ...]:
    return ((front, -half_width), (front, half_width), (-back, half_width), (-back, -half_width))


def _front_ir(x: float, y: float) -> tuple[IRSensorSpec, ...]:
    return (IRSensorSpec("ir_left", (x, y), 0.0, side="left"), IRSensorSpec("ir_right", (x, -y), 0.0, side="right"))


OMNI3 = wheeled_robot(
    "omni3",
    ChassisSpec(chassis_presets.omni3(radius=0.15, wheel_radius=0.03, max_speed=1.0),
                mouse2=MouseSpec(mount=(-0.06, 0.05))),
    body_radius=0.19, mass=3.0, mouse=MouseSpec(mount=(0.06, 0.0)), ir=_front_ir(0.18, 0.05),
)
"""Three omni wheels 120° apart, 0.15 m from the centre, r = 30 mm, 1 m/s rims; two mice."""

MECANUM4 = wheeled_robot(
    "mecanum4",
    ChassisSpec(chassis_presets.mecanum4(wheelbase=0.43, track=0.23, wheel_radius=0.05, max_speed=1.0),
                outline=_box(0.3, 0.3, 0.2), mouse2=MouseSpec(mount=(-0.1, 0.08))),
    mass=8.0, mouse=MouseSpec(mount=(0.1, 0.0)), ir=_front_ir(0.29, 0.1),
)
"""Mecanum wheels at (±0.215, ±0.115) m, r = 50 mm, 1 m/s rims, a 0.6 × 0.4 m body; two mice."""

CAR = wheeled_robot(
    "car",
    ChassisSpec(chassis_presets.ackermann(wheelbase=0.5, track=0.4, wheel_radius=0.05, max_speed=1.5,
                                          steer_limit=math.radians(35)),
                outline=_box(0.65, 0.15, 0.25), steer_rate=2.0, infeasible="project"),
    mass=10.0, mouse=MouseSpec(mount=(0.25, 0.0)), ir=_front_ir(0.64, 0.15),
)
"""Ackermann car: free front wheels steered ±35° at 2 rad/s, driven rear axle (P mid rear axle),
wheelbase 0.5 m, track 0.4 m, 1.5 m/s rims, a 0.8 × 0.5 m body; one mouse (the rear axle's
constraint gives the rest). It projects what it cannot do (`infeasible="project"`), as a driver
would: a turn tighter than its R_min = 0.5 m / tan 35° + 0.2 m ≈ 0.914 m becomes its tightest turn
at the commanded speed (turn on the spot: at the commanded yaw rate, driving forwards), a sideways
twist loses its sideways part; each run notes what it changed."""

OCP_VEHICLE = wheeled_robot(
    "ocp_vehicle",
    ChassisSpec(chassis_presets.steered4(max_speed=1.0), outline=_box(0.3, 0.3, 0.2), steer_rate=3.0),
    mass=12.0, mouse=MouseSpec(mount=(0.1, 0.0)), ir=_front_ir(0.29, 0.1),
)
"""The OCP paper's IFT vehicle: four driven steered wheels (±155°) at (±0.215, ±0.115) m, 1 m/s rims."""

WHEELED_ROBOTS: dict[str, RobotSpec] = {r.name: r for r in (OMNI3, MECANUM4, CAR, OCP_VEHICLE)}
"""The shipped general-chassis robots by name, for the command line."""

