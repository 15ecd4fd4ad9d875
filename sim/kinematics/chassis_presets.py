"""Chassis presets: the chassis of both spec sources, as functions with keyword parameters (m, rad, m/s).

Each returns a `Chassis` with its reference point where the sources put it; wheels point straight
ahead (heading 0) unless said otherwise. `max_speed` is every driven wheel's rim-speed limit.
"""

from __future__ import annotations

import numpy as np

from sim.kinematics.chassis import Chassis, Wheel, WheelType

_CTBOT_TRACK = 0.0972
_CTBOT_WHEEL_RADIUS = 0.0567 / 2
_CTBOT_MAX_RIM_SPEED = 151 / 60 * 2 * np.pi * _CTBOT_WHEEL_RADIUS  # 151 rpm motors (bots/ctbot.py)


def differential_drive(track: float = _CTBOT_TRACK, wheel_radius: float = _CTBOT_WHEEL_RADIUS,
                       max_speed: float = np.inf) -> Chassis:
    """Two driven fixed wheels, left at (0, b/2) and right at (0, −b/2); P mid-axle (thesis §3.2)."""
    return Chassis.from_wheels([
        Wheel.placed(WheelType.FIXED, 0.0, side * track / 2, radius=wheel_radius, max_speed=max_speed, name=name)
        for side, name in ((1, "left"), (-1, "right"))
    ])


def ctbot() -> Chassis:
    """The c't-Bot: track 97.2 mm, wheels 56.7 mm, 151 rpm motors; its skid is not a wheel."""
    return differential_drive(_CTBOT_TRACK, _CTBOT_WHEEL_RADIUS, _CTBOT_MAX_RIM_SPEED)


def tricycle(wheelbase: float = 0.5, track: float = 0.4, wheel_radius: float = 0.05,
             max_speed: float = np.inf, steer_limit: float = np.inf) -> Chassis:
    """Steered, driven front wheel at (a, 0), free fixed rear wheels at (0, ±b/2); P mid rear axle;
    the front wheel's heading limited to ±`steer_limit` (rad).

    With track = 0 it is the paper's single-track (bicycle) model of Ackermann steering (OCP §2.7).
    """
    return Chassis.from_wheels([
        Wheel.placed(WheelType.STEERED, wheelbase, 0.0, radius=wheel_radius, max_speed=max_speed,
                     steer_limits=(-steer_limit, steer_limit), name="front"),
        Wheel.placed(WheelType.FIXED, 0.0, track / 2, radius=wheel_radius, driven=False, name="rear left"),
        Wheel.placed(WheelType.FIXED, 0.0, -track / 2, radius=wheel_radius, driven=False, name="rear right"),
    ])


def ackermann(wheelbase: float = 0.5, track: float = 0.4, wheel_radius: float = 0.05,
              max_speed: float = np.inf, steer_limit: float = np.inf) -> Chassis:
    """Car: free steered front wheels at (a, ±b/2), driven fixed rear wheels at (0, ±b/2); P mid rear axle.

    Steering each front wheel at the ICR gives the Ackermann angles (thesis 2.2.2, Abb. 23). With the
    front wheels' headings limited to ±`steer_limit` (rad), the inner wheel limits the turn: the ICR
    stays at least R_min = a / tan(steer_limit) + b/2 from P.
    """
    limits = (-steer_limit, steer_limit)
    return Chassis.from_wheels([
        Wheel.placed(WheelType.STEERED, wheelbase, track / 2, radius=wheel_radius, driven=False,
                     steer_limits=limits, name="front left"),
        Wheel.placed(WheelType.STEERED, wheelbase, -track / 2, radius=wheel_radius, driven=False,
                     steer_limits=limits, name="front right"),
        Wheel.placed(WheelType.FIXED, 0.0, track / 2, radius=wheel_radius, max_speed=max_speed, name="rear left"),
        Wheel.placed(WheelType.FIXED, 0.0, -track / 2, radius=wheel_radius, max_speed=max_speed, name="rear right"),
    ])


def mecanum4(wheelbase: float = 0.43, track: float = 0.23, wheel_radius: float = 0.05,
             max_speed: float = np.inf) -> Chassis:
    """Mecanum wheels FL, FR, RL, RR at (±a/2, ±b/2), rollers at 45°, diagonals alike (OCP §2.3).

    Roller angle γ = −atan(σ) with σ = (+1, −1, −1, +1), so that r φ̇ = v_cx − σ v_cy (the standard M).
    """
    corners = ((1, 1, "front left"), (1, -1, "front right"), (-1, 1, "rear left"), (-1, -1, "rear right"))
    return Chassis.from_wheels([
        Wheel.placed(WheelType.OMNI, sx * wheelbase / 2, sy * track / 2, radius=wheel_radius,
                     gamma=-sx * sy * np.pi / 4, max_speed=max_speed, name=name)
        for sx, sy, name in corners
    ])


def _ring(kind: WheelType, angles_deg: tuple[float, ...], radius: float, wheel_radius: float,
          max_speed: float, beta: float | None) -> Chassis:
    """Wheels at distance `radius` and angles α; β given, or None to point straight ahead."""
    wheels = []
    for i, a in enumerate(np.radians(angles_deg)):
        b = float(np.pi / 2 - a) if beta is None else beta
        wheels.append(Wheel(kind, radius, float(a), b, wheel_radius, max_speed=max_speed, name=f"wheel {i + 1}"))
    return Chassis.from_wheels(wheels)


def omni3(radius: float = 0.2, wheel_radius: float = 0.02, max_speed: float = np.inf) -> Chassis:
    """Three omni wheels (γ = 0) at α = 0°, 120°, −120°, β = 0, distance l from P."""
    return _ring(WheelType.OMNI, (0, 120, -120), radius, wheel_radius, max_speed, 0.0)


def omni4(radius: float = 0.2, wheel_radius: float = 0.02, max_speed: float = np.inf) -> Chassis:
    """The thesis's old RoboCup chassis (§3.1): omni wheels (γ = 0) at α = 0°, 90°, 180°, 270°, β = 0,
    l = 0.2 m, r = 0.02 m; positive φ̇ pushes every contact point clockwise."""
    return _ring(WheelType.OMNI, (0, 90, 180, -90), radius, wheel_radius, max_speed, 0.0)


def steered3(radius: float = 0.2, wheel_radius: float = 0.02, max_speed: float = np.inf) -> Chassis:
    """The thesis's new RoboCup chassis (§3.4): driven steered wheels at α = 0°, 120°, −120°, l = 0.2 m."""
    return _ring(WheelType.STEERED, (0, 120, -120), radius, wheel_radius, max_speed, None)


def steered4(wheelbase: float = 0.43, track: float = 0.23, wheel_radius: float = 0.05,
             steer_limit: float = np.radians(155), max_speed: float = np.inf) -> Chassis:
    """The OCP paper's IFT vehicle (§2.8): driven steered wheels W₁..W₄ = FL, FR, RL, RR at
    (±a/2, ±b/2), P at the centre, headings limited to ±`steer_limit`."""
    corners = ((1, 1, "W1 front left"), (1, -1, "W2 front right"), (-1, 1, "W3 rear left"),
               (-1, -1, "W4 rear right"))
    return Chassis.from_wheels([
        Wheel.placed(WheelType.STEERED, sx * wheelbase / 2, sy * track / 2, radius=wheel_radius,
                     max_speed=max_speed, steer_limits=(-steer_limit, steer_limit), name=name)
        for sx, sy, name in corners
    ])
