"""Steering limits as part of feasibility: refused or projected (the tightest turn), never clipped by the world."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from bots.chassis_commands import InfeasibleCommand, chassis_setpoints
from bots.chassis_spec import ChassisSpec
from bots.commands import Twist
from bots.controller import FunctionController
from bots.readings import Readings
from bots.spec import MotorSpec, wheeled_robot
from bots.wheeled import CAR, OCP_VEHICLE
from sim.kinematics import apply_increment, relative_increment, se2_exp, se2_log, wrap_angle
from sim.kinematics import chassis_presets as presets
from sim.kinematics.chassis import (
    InfeasibleTwist,
    check_steering,
    inverse_kinematics,
    is_feasible,
    is_steerable,
    nearest_feasible,
    nearest_steerable,
)
from sim.run.loop import RobotSetup, run
from sim.world import World
from sim.world.spec import Start, WorldSpec

DT = 0.01
EMPTY = WorldSpec("empty", (-20, -20, 20, 20), starts=(Start(0.3, -0.2, 0.4),))
FAST = MotorSpec(max_wheel_speed=200.0)  # no motor limit in the way of the commanded speeds
LIMIT = math.radians(35)
WHEELBASE, TRACK = 0.5, 0.4  # the shipped car's
R_MIN = WHEELBASE / math.tan(LIMIT) + TRACK / 2
"""The car's tightest turn about the rear axle's middle P: the inner front wheel at its 35° stop
points at the ICR, tan 35° = a / (R − b/2)."""
REFUSING_CAR = CAR.with_changes(chassis={"infeasible": "refuse"}, motor=FAST)
PROJECTING_CAR = CAR.with_changes(motor=FAST)


def heading_of(chassis, beta):
    return wrap_angle(chassis.alpha + beta - np.pi / 2)


def test_the_shipped_cars_geometry_gives_the_closed_form_tightest_turn():
    c = CAR.chassis.chassis
    assert_allclose(c.positions[0], [WHEELBASE, TRACK / 2])
    assert_allclose(c.steer_max[:2], LIMIT) and np.all(np.isinf(c.steer_max[2:]))  # rear wheels are fixed
    assert is_steerable(c, [0.3, 0.0, 0.3 / R_MIN])
    assert not is_steerable(c, [0.3, 0.0, 0.3 / R_MIN * (1 + 1e-6)])  # 1e-6 rad past the stop: > 1e-9 slack


def test_a_car_refuses_a_turn_beyond_its_steering_limits_naming_the_wheel_and_angles():
    readings = Readings(steering=CAR.chassis.chassis.beta)
    with pytest.raises(InfeasibleCommand) as refusal:
        chassis_setpoints(Twist(0.3, 1.0), REFUSING_CAR, readings)  # R = 0.3 m < R_MIN
    message = str(refusal.value)
    inner = math.degrees(math.atan2(WHEELBASE, 0.3 - TRACK / 2))  # 78.7°: the inner wheel, at R − b/2
    assert "refused" in message and "beyond the steering limits" in message
    assert f"front left would have to roll at {inner:.1f}°" in message
    assert "-35.0°..35.0°" in message and "tightest steerable turn" in message
    with pytest.raises(InfeasibleCommand, match="front right would have to roll at"):
        chassis_setpoints(Twist(0.0, -1.0), REFUSING_CAR, readings)  # on the spot, to the right


def test_a_twist_exactly_at_the_limit_is_accepted_and_steers_the_inner_wheel_to_its_stop():
    readings = Readings(steering=CAR.chassis.chassis.beta)
    for sign in (1, -1):
        twist = Twist(0.3, sign * 0.3 / R_MIN)
        setpoint = chassis_setpoints(twist, REFUSING_CAR, readings)
        assert setpoint.note is None
        inner = 0 if sign > 0 else 1
        heading = heading_of(CAR.chassis.chassis, setpoint.beta)
        assert heading[inner] == pytest.approx(sign * LIMIT, abs=1e-12)  # rounding of atan2 of m-sized terms
        assert abs(heading[1 - inner]) < LIMIT


def test_reversing_takes_the_mirrored_wheel_angle_within_the_limits():
    """Backwards in a tight left turn the front wheels' contact points move at 180° − δ, beyond 90°;
    the wheel realises that by the mirror −δ, within ±35°, rolling backwards."""
    c = CAR.chassis.chassis
    twist = np.array([-0.3, 0.0, 0.3 / R_MIN])  # backwards, ICR on the right at R_MIN
    moving = np.degrees(np.arctan2(twist[2] * c.positions[:, 0], twist[0] - twist[2] * c.positions[:, 1]))[:2]
    assert np.all(np.abs(moving) > 90)
    check_steering(c, twist)
    setpoint = chassis_setpoints(Twist(-0.3, 0.3 / R_MIN), REFUSING_CAR, Readings(steering=c.beta))
    heading = heading_of(c, setpoint.beta)
    assert_allclose(np.degrees(heading[:2]), wrap_angle(np.radians(moving) + np.pi) * 180 / np.pi, atol=1e-9)
    assert np.all(np.abs(heading[:2]) <= LIMIT + 1e-12)
    assert np.all(inverse_kinematics(c, twist).phi_dot[:2] < 0)  # rolling backwards


def test_inverse_kinematics_prefers_the_branch_within_the_limits_over_the_nearer_one():
    """The OCP vehicle (±155°) heading at 150°, asked to roll along 170°: the nearer setting lies in its
    stops' gap, so it takes −10° and rolls backwards."""
    c = OCP_VEHICLE.chassis.chassis
    near = c.with_beta(np.radians(150) - c.alpha + np.pi / 2)  # every wheel heading 150°
    twist = 0.2 * np.array([np.cos(np.radians(170)), np.sin(np.radians(170)), 0.0])
    command = inverse_kinematics(near, twist)
    assert_allclose(np.degrees(command.heading), -10.0, atol=1e-9)
    assert np.all(command.phi_dot < 0)


def projected_run(command: Twist, seconds: float = 3.0):
    result = run(EMPTY, [RobotSetup(PROJECTING_CAR, FunctionController(lambda t, r: command))], seconds)
    assert result.reason == "duration", result.error
    return result.robots[0]


def body_icr(truth: np.ndarray) -> tuple[np.ndarray, float]:
    """ICR (body frame of the step's start, m) and yaw rate (rad/s) of the last step."""
    step = se2_log(relative_increment(truth[-2], truth[-1])) / DT
    return np.array([-step[1], step[0]]) / step[2], step[2]


@pytest.mark.parametrize("v, omega", [(0.3, 2.0), (0.3, -1.0), (-0.2, 1.5)])
def test_a_projecting_car_drives_its_tightest_turn_at_the_commanded_speed(v, omega):
    log = projected_run(Twist(v, omega))
    centre, rate = body_icr(log.truth_array())
    # steering settled (0.7 rad at 2 rad/s) long before the end; rounding of a 1e-2 rad step over ω
    assert_allclose(centre, [0.0, math.copysign(R_MIN, omega * v)], atol=1e-9)
    assert rate == pytest.approx(math.copysign(abs(v) / R_MIN, omega), rel=1e-9)
    (message, count), = log.notes.values()
    assert message.startswith("step 0 ") and "projected" in message and "beyond the steering limits" in message
    assert count == len(log) - 1  # every step's command was projected, and noted as one kind


@pytest.mark.parametrize("omega", [1.0, -0.8])
def test_turn_on_the_spot_on_a_car_is_its_tightest_forward_circle_at_the_commanded_yaw_rate(omega):
    """What a user gets who presses only "turn" on the keyboard (teleop sends Twist(0, ω))."""
    log = projected_run(Twist(0.0, omega))
    centre, rate = body_icr(log.truth_array())
    assert_allclose(centre, [0.0, math.copysign(R_MIN, omega)], atol=1e-9)
    assert rate == pytest.approx(omega, rel=1e-9)
    truth = log.truth_array()
    forward = relative_increment(truth[-2], truth[-1])[0]
    assert forward == pytest.approx(abs(omega) * R_MIN * DT, rel=1e-3)  # forwards; chord vs arc of 1e-2 rad


def test_a_refusing_car_stops_the_run_with_the_steering_message():
    result = run(EMPTY, [RobotSetup(REFUSING_CAR, FunctionController(lambda t, r: Twist(0.0, 1.0)))], 1.0)
    assert result.reason == "error" and "front left would have to roll at" in result.error


def test_a_wheel_steered_beyond_its_stop_is_held_there_with_one_warning(caplog):
    spec = REFUSING_CAR.with_changes(chassis={"steer_rate": math.inf})
    world = World(EMPTY, dt=DT)
    world.add_robot(spec)
    c = spec.chassis.chassis
    beta = c.beta + np.radians([50.0, 20.0, 0.0, 0.0])  # front left 50° from straight: beyond its 35° stop
    with caplog.at_level(logging.WARNING, logger="sim.world.chassis_drive"):
        for _ in range(3):
            world.chassis.command(0, np.zeros(4), beta)
            world.step(np.zeros((1, 2)))
    heading = heading_of(c, world.chassis.drives[0].beta)
    assert_allclose(np.degrees(heading[:2]), [35.0, 20.0], atol=1e-9)
    (record,) = caplog.records
    assert "front left steered to 50.0°, beyond its stops -35.0°..35.0°: held at the stop" in record.getMessage()


def test_a_wide_range_wheel_turns_the_way_inside_its_stops():
    """The OCP vehicle's wheels (±155°) from 150° to −150°: the short way (60°) crosses the stops' gap,
    so they turn the long way (300°) through 0°, and never leave their range."""
    world = World(EMPTY, dt=DT)
    world.add_robot(OCP_VEHICLE)
    c = OCP_VEHICLE.chassis.chassis
    start, goal = (np.radians(h) - c.alpha + np.pi / 2 for h in (150.0, -150.0))
    headings = []
    for target in [start] * 200 + [goal] * 200:  # 3 rad/s: 0.9 s to 150°, 1.75 s round to −150°
        world.chassis.command(0, np.zeros(4), target)
        world.step(np.zeros((1, 2)))
        headings.append(heading_of(c, world.chassis.drives[0].beta))
    headings = np.degrees(np.array(headings))
    assert np.all(np.abs(headings) <= 155.0 + 1e-9)
    assert_allclose(headings[199], 150.0, atol=1e-9) and assert_allclose(headings[-1], -150.0, atol=1e-9)
    assert np.any(np.abs(headings[200:]) < 1.0)  # through straight ahead


LIMITED = {  # chassis with steering limits, narrow and wide (the mirror matters for the wide ones)
    "car": CAR.chassis.chassis,
    "tricycle ±50°": presets.tricycle(steer_limit=math.radians(50)),
    "steered4 ±35°": presets.steered4(steer_limit=math.radians(35)),
    "ocp_vehicle ±155°": OCP_VEHICLE.chassis.chassis,
}
component = st.floats(-0.6, 0.6, allow_nan=False)


@settings(max_examples=60)
@given(st.sampled_from(sorted(LIMITED)), component, component, component)
def test_every_accepted_twist_lands_on_the_exact_integral_and_never_meets_a_stop(name, vx, vy, omega):
    """A random twist, projected onto B; if the steering check accepts it, the robot drives it, else
    its projection `nearest_steerable`, which the check must accept. Executed in the world (steering
    at once, no motor limit), the body lands on the core's exact SE(2) integration and the world's
    steering equals the command: no stop was hit."""
    chassis = LIMITED[name]
    twist = nearest_feasible(chassis, [vx, vy, omega])
    if not is_steerable(chassis, twist):
        with pytest.raises(InfeasibleTwist):
            check_steering(chassis, twist)
        twist = nearest_steerable(chassis, twist)
    check_steering(chassis, twist)
    assert is_feasible(chassis, twist)
    spec = wheeled_robot("t", ChassisSpec(chassis, steer_rate=math.inf), body_radius=0.3, motor=FAST)
    setpoint = chassis_setpoints(Twist(twist[0], twist[2], vy=twist[1]), spec, Readings(steering=chassis.beta))
    assert setpoint.note is None
    world = World(EMPTY, dt=DT)
    world.add_robot(spec)
    pose = world.poses()[0]
    for _ in range(20):
        world.chassis.command(0, setpoint.phi_dot, setpoint.beta)
        world.step(np.zeros((1, 2)))
        pose = apply_increment(pose, se2_exp(setpoint.twist * DT))
        assert_allclose(world.chassis.drives[0].beta, wrap_angle(setpoint.beta), rtol=0, atol=0)
    assert not world.chassis.drives[0].held
    # 20 compositions of rounding (1e-16 relative) on metres: far below the 1e-9 m contract
    assert np.linalg.norm(world.poses()[0][:2] - pose[:2]) < 1e-9
    assert abs(wrap_angle(world.poses()[0][2] - pose[2])) < 1e-9


@settings(max_examples=100)
@given(component.filter(lambda v: v == 0 or abs(v) > 1e-6), component)  # clear of the core's 1e-9 m/s "no speed"
def test_the_cars_projection_keeps_its_speed_and_turns_no_tighter_than_r_min(v, omega):
    c = CAR.chassis.chassis
    twist = np.array([v, 0.0, omega])
    nearest = nearest_steerable(c, twist)
    assert is_steerable(c, nearest)
    if is_steerable(c, twist):
        assert_allclose(nearest, twist, rtol=0, atol=0)
    elif v != 0:  # tightest turn at the commanded speed
        assert_allclose(nearest, [v, 0.0, math.copysign(abs(v) / R_MIN, omega)], rtol=1e-9, atol=1e-15)
    else:  # on the spot: at the commanded yaw rate, forwards
        assert_allclose(nearest, [abs(omega) * R_MIN, 0.0, omega], rtol=1e-9, atol=1e-15)


def test_keyboard_turn_on_the_spot_drives_the_shipped_car_round_its_tightest_circle():
    """`ctsim play --robot car`, only "left" held: teleop asks Twist(0, 90°/s); the car drives forwards
    about (0, R_MIN), as fast as its outer rear wheel allows (1.5 m/s rims: the yaw rate is scaled
    down to 1.5 / (R_MIN + b/2), keeping the circle)."""
    from bots.behaviours.motion import Teleop

    teleop = Teleop()
    teleop.set_keys({"left"})
    result = run(EMPTY, [RobotSetup(CAR, teleop)], 2.0)
    assert result.reason == "duration", result.error
    centre, rate = body_icr(result.robots[0].truth_array())
    assert_allclose(centre, [0.0, R_MIN], atol=1e-9)
    assert rate == pytest.approx(1.5 / (R_MIN + TRACK / 2), rel=1e-9)
    (message, _), = result.robots[0].notes.values()
    assert "tightest steerable turn" in message
