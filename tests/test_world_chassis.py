"""Robots on general wheeled chassis in the world: exact motion, ICR, refusals, faults, odometry, slip."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from bots.chassis_commands import InfeasibleCommand, chassis_setpoints
from bots.chassis_spec import PRESETS, ChassisSpec
from bots.commands import Twist, WheelCommands
from bots.controller import FunctionController
from bots.odometry.chassis import ChassisEncoderOdometry, ChassisMouseOdometry, mouse_applies
from bots.readings import Readings
from bots.spec import EncoderSpec, MotorSpec, MouseSpec, load_robot, wheeled_robot
from bots.wheeled import CAR, MECANUM4, WHEELED_ROBOTS
from sim.kinematics import (
    apply_increment,
    relative_increment,
    se2_exp,
    se2_log,
    wrap_angle,
)
from sim.kinematics.chassis import (
    Failure,
    WheelType,
    degrade,
    forward_kinematics,
    inverse_kinematics,
    motion_subspaces,
    nearest_feasible,
    null_space,
)
from sim.run.loop import RobotSetup, run
from sim.world import World
from sim.world.spec import Start, Wall, WheelFault, WorldSpec, box

DT = 0.01
EMPTY = WorldSpec("empty", (-20, -20, 20, 20), starts=(Start(0.3, -0.2, 0.4),))
FAST = MotorSpec(max_wheel_speed=200.0)  # no motor limit in the way of the commanded speeds
FINE = EncoderSpec(ticks_per_rev=2**40)  # quantisation below 1e-11 rad per step: "without quantisation"


def robot_on(chassis, **fields):
    return wheeled_robot("test", ChassisSpec(chassis, **fields.pop("chassis_fields", {})), body_radius=0.3,
                         motor=fields.pop("motor", FAST), **fields)


def drive_world(spec, phi_dot, beta, steps: int, world_spec: WorldSpec = EMPTY) -> tuple[World, np.ndarray]:
    """Step a world with constant wheel set-points; the truth poses (steps + 1, 3)."""
    world = World(world_spec, dt=DT)
    world.add_robot(spec)
    poses = [world.poses()[0]]
    for _ in range(steps):
        world.chassis.command(0, phi_dot, beta)
        world.step(np.zeros((1, 2)))
        poses.append(world.poses()[0])
    return world, np.array(poses)


def integrate(pose: np.ndarray, twist: np.ndarray, steps: int) -> np.ndarray:
    for _ in range(steps):
        pose = apply_increment(pose, se2_exp(twist * DT))
    return pose


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_unobstructed_truth_is_the_exact_integral_of_forward_kinematics(preset):
    """Random (generally inconsistent) wheel speeds at fixed steering: the least-squares twist, exactly."""
    chassis = PRESETS[preset]()
    rng = np.random.default_rng(sum(map(ord, preset)))
    phi_dot = rng.uniform(-8, 8, chassis.n)
    beta = chassis.beta + rng.uniform(-0.5, 0.5, chassis.n) * (chassis.kind == 1)
    _, poses = drive_world(robot_on(chassis), phi_dot, beta, 300)
    twist = forward_kinematics(chassis, phi_dot * chassis.driven, beta, measured=chassis.driven).twist
    # 300 compositions of rounding (1e-16 relative) on metres: far below the 1e-9 m contract
    assert np.linalg.norm(poses[-1, :2] - integrate(poses[0], twist, 300)[:2]) < 1e-9
    assert abs(poses[-1, 2] - integrate(poses[0], twist, 300)[2]) < 1e-9


@pytest.mark.parametrize("radius", [1.0, -0.7, 3.0])
def test_ackermann_icr_lies_on_the_rear_axle_where_the_wheel_angles_meet(radius):
    """Front wheels at the closed-form Ackermann angles δ = atan(a/(R ∓ b/2)) and rear wheels at
    ω(R ∓ b/2)/r turn the body about (0, R) (thesis 2.2.2, Abb. 23)."""
    a, b, r, omega = 0.5, 0.4, 0.05, 0.3
    chassis = PRESETS["ackermann"](wheelbase=a, track=b, wheel_radius=r)
    delta = np.arctan(a / (radius - np.array([b / 2, -b / 2])))
    heading = np.array([*delta, 0.0, 0.0])
    beta = heading - chassis.alpha + np.pi / 2
    phi_dot = np.array([0.0, 0.0, omega * (radius - b / 2) / r, omega * (radius + b / 2) / r])
    _, poses = drive_world(robot_on(chassis), phi_dot, beta, 50)
    step = se2_log(relative_increment(poses[10], poses[11])) / DT
    icr = np.array([-step[1], step[0]]) / step[2]
    assert_allclose(icr, [0.0, radius], atol=1e-9)  # rounding of a 1e-2 rad step, divided by ω
    assert_allclose(step[2], omega, rtol=1e-9)


def wheels_about(chassis, centre: np.ndarray, omega: float, keep: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Wheel speeds φ̇ and angles β that turn the body about `centre` (body frame) at `omega`, by the
    thesis's rule (2.99-2.110): each wheel rolls along ω × (wheel − ICR), at that contact speed; a
    steered wheel whose direction lies beyond its limits rolls the other way round. Fixed wheels
    (and those in `keep`) keep their β: the ICR must lie on their axles."""
    offset = chassis.positions - centre
    velocity = omega * np.stack([-offset[:, 1], offset[:, 0]], axis=1)
    heading = np.arctan2(velocity[:, 1], velocity[:, 0])
    heading = np.where((heading < chassis.steer_min) | (heading > chassis.steer_max), wrap_angle(heading + np.pi), heading)
    keep = (chassis.kind == WheelType.FIXED) | (False if keep is None else keep)
    beta = np.where(keep, chassis.beta, heading - chassis.alpha + np.pi / 2)
    rolls = chassis.alpha + beta - np.pi / 2
    return (velocity[:, 0] * np.cos(rolls) + velocity[:, 1] * np.sin(rolls)) / chassis.radius, beta


STEERED_ICRS = {  # preset -> ICRs (body frame, m) its wheels can point at within their limits
    "tricycle": [(0.0, 1.2), (0.0, -0.6), (0.0, 0.1)],  # on the rear axle, even between the wheels
    "steered3": [(0.5, -0.3), (0.05, 0.1), (-0.4, 0.0)],  # anywhere: outside, inside the chassis
    "steered4": [(0.1, 0.6), (-0.8, 0.0), (0.0, 0.0)],  # the OCP vehicle: beside, behind, on the spot
}


@pytest.mark.parametrize("preset, centre", [(p, c) for p, centres in STEERED_ICRS.items() for c in centres])
def test_steered_chassis_turn_about_the_icr_their_wheels_point_at(preset, centre):
    """The ICR of the world's motion is where the thesis puts it for the commanded wheel angles."""
    chassis = PRESETS[preset]()
    phi_dot, beta = wheels_about(chassis, np.array(centre), 0.4)
    _, poses = drive_world(robot_on(chassis), phi_dot, beta, 20)
    step = se2_log(relative_increment(poses[10], poses[11])) / DT
    assert step[2] == pytest.approx(0.4, rel=1e-9)  # the wheels agree: no least-squares compromise
    assert_allclose(np.array([-step[1], step[0]]) / step[2], centre, atol=1e-9)  # rounding, divided by ω


def test_steered3_with_wheel_3_frozen_at_30_degrees_turns_only_about_points_of_its_axle():
    """Thesis §3.4 case 2: with wheel 3's steering frozen at β₃ = 30° the ICR lies on wheel 3's axle
    line; the other two wheels, pointed at a point of that line, turn the robot about it."""
    chassis = PRESETS["steered3"]()
    frozen = chassis.beta.copy()
    frozen[2] = wrap_angle(frozen[2] + math.radians(30))
    heading = chassis.alpha[2] + frozen[2] - np.pi / 2  # wheel 3 rolls along this; its axle is normal to it
    centre = chassis.positions[2] + 0.7 * np.array([-np.sin(heading), np.cos(heading)])
    phi_dot, beta = wheels_about(chassis.with_beta(frozen), centre, -0.3, keep=np.arange(3) == 2)
    spec = robot_on(chassis, chassis_fields={"steer_rate": math.inf})
    world = World(EMPTY, dt=DT)
    world.add_robot(spec)
    world.chassis.command(0, np.zeros(3), frozen)
    world.step(np.zeros((1, 2)))
    world.chassis.fail(0, 2, "steering")
    poses = []
    for _ in range(12):
        world.chassis.command(0, phi_dot, beta + np.array([0.0, 0.0, 0.5]))  # wheel 3's steering ignores its command
        world.step(np.zeros((1, 2)))
        poses.append(world.poses()[0])
    step = se2_log(relative_increment(poses[-2], poses[-1])) / DT
    assert_allclose(world.chassis.drives[0].beta[2], frozen[2], atol=1e-12)
    assert step[2] == pytest.approx(-0.3, rel=1e-9)
    assert_allclose(np.array([-step[1], step[0]]) / step[2], centre, atol=1e-9)


def constant(command):
    return FunctionController(lambda t, readings: command)


REFUSING_CAR = CAR.with_changes(chassis={"infeasible": "refuse"})
"""The shipped car projects (a driver's car); robots refuse by default."""


def test_a_car_refuses_to_move_sideways_and_says_which_wheels():
    result = run(EMPTY, [RobotSetup(REFUSING_CAR, constant(Twist(0.0, 0.0, vy=0.3)))], 1.0)
    assert result.reason == "error"
    assert "refused" in result.error and "rear left, rear right slide sideways" in result.error
    assert "nearest feasible" in result.error


def test_a_projecting_car_drives_the_nearest_feasible_twist_and_says_so():
    assert CAR.chassis.infeasible == "project" and robot_on(CAR.chassis.chassis).chassis.infeasible == "refuse"
    result = run(EMPTY, [RobotSetup(CAR, constant(Twist(0.4, 0.0, vy=0.3)))], 1.0)
    log = result.robots[0]
    assert result.reason == "duration"
    (message, count), = log.notes.values()
    assert "projected" in message and "slide sideways" in message and count == 100
    truth = log.truth_array()
    sideways = [relative_increment(truth[k], truth[k + 1])[1] for k in range(len(truth) - 1)]
    assert np.max(np.abs(sideways)) < 1e-12  # the projection has no lateral part: none at all


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_every_preset_refuses_or_projects_what_it_cannot_do_as_its_policy_says(preset):
    """Each direction outside span(B) is refused naming the sliding wheels, or projected onto B with a
    note; a twist in B passes unchanged (presets without fixed wheels can do any twist)."""
    chassis = PRESETS[preset]()
    readings = Readings(steering=chassis.beta)
    b = motion_subspaces(chassis).B
    inside = 0.1 * b.sum(axis=1)
    setpoint = chassis_setpoints(Twist(inside[0], inside[2], vy=inside[1]), robot_on(chassis), readings)
    assert setpoint.note is None
    assert_allclose(setpoint.twist, inside, atol=1e-15)
    assert (b.shape[1] < 3) == (preset in ("differential", "tricycle", "ackermann"))
    for outside in 0.1 * null_space(b.T).T:
        command = Twist(outside[0], outside[2], vy=outside[1])
        with pytest.raises(InfeasibleCommand, match="refused: .* slide sideways"):
            chassis_setpoints(command, robot_on(chassis), readings)
        projected = chassis_setpoints(command, robot_on(chassis, chassis_fields={"infeasible": "project"}), readings)
        assert "projected" in projected.note
        assert_allclose(projected.twist, 0.0, atol=1e-15)  # orthogonal to B: its projection is standing still


THESIS_FAULTS = {
    "omni4 drive 4": ("omni4", [(3, "free")]),
    "omni4 drives 3+4": ("omni4", [(2, "free"), (3, "free")]),
    "omni4 drives 2+4": ("omni4", [(1, "free"), (3, "free")]),
    "omni4 drives 2+3+4": ("omni4", [(1, "free"), (2, "free"), (3, "free")]),
    "steered3 steering 3 at 30°": ("steered3", [(2, "steering")]),
    "steered3 steering 1, drive 2": ("steered3", [(0, "steering"), (1, "free")]),
    "mecanum4 wheel 1 locked": ("mecanum4", [(0, "lock")]),
}


@pytest.mark.parametrize("case", sorted(THESIS_FAULTS))
def test_after_each_thesis_failure_the_robot_follows_every_feasible_twist_and_refuses_the_rest(case):
    preset, faults = THESIS_FAULTS[case]
    nominal = PRESETS[preset]()
    pre_steer = nominal.beta.copy()
    if preset == "steered3":
        pre_steer[[w for w, _ in faults if _ == "steering"]] += math.radians(30)
    believed = degrade(nominal.with_beta(pre_steer), *(
        Failure(w, drive=k == "free", steering=k == "steering", locked=k == "lock") for w, k in faults))
    b = motion_subspaces(believed).B
    feasible = [0.1 * b[:, k] for k in range(b.shape[1])] + ([0.07 * b.sum(axis=1)] if b.shape[1] else [])
    infeasible = [0.1 * v for v in null_space(b.T).T] if b.shape[1] < 3 else []
    assert feasible or infeasible
    for twist in feasible + infeasible:
        def controller(t, readings, twist=twist):
            if t < 0.02:  # pre-steer, then the faults strike at t = 0.015 s
                return WheelCommands(tuple(np.zeros(nominal.n)), tuple(pre_steer))
            return Twist(twist[0], twist[2], vy=twist[1])
        spec = robot_on(nominal, chassis_fields={"steer_rate": math.inf})
        setup = RobotSetup(spec, FunctionController(controller), faults=tuple(WheelFault(0.015, w, k) for w, k in faults))
        result = run(EMPTY, [setup], 0.2)
        if any(twist is v for v in infeasible):
            assert result.reason == "error" and "refused" in result.error, case
            continue
        assert result.reason == "duration", result.error
        truth = result.robots[0].truth_array()
        expected = integrate(truth[3], twist, len(truth) - 4)
        assert np.linalg.norm(truth[-1, :2] - expected[:2]) < 1e-9, case  # exact motion, rounding only
        assert result.robots[0].latest.failures


ODOMETRY_ROBOTS = {**WHEELED_ROBOTS, **{f"preset {p}": robot_on(PRESETS[p]()) for p in PRESETS}}
"""The shipped robots and every preset of the core (on a round body, no motor limit)."""


@pytest.mark.parametrize("name", sorted(ODOMETRY_ROBOTS))
def test_encoder_odometry_is_exact_without_quantisation(name):
    spec = ODOMETRY_ROBOTS[name].with_changes(encoders=FINE, motor=FAST)
    result = run(EMPTY, [RobotSetup(spec, constant(Twist(0.3, 0.4)))], 3.0)
    log = result.robots[0]
    error = np.linalg.norm(log.estimate_arrays()["encoders"][:, :2] - log.truth_array()[:, :2], axis=1)
    assert error.max() < 1e-9  # 2**40 ticks per turn: 6e-12 rad per wheel, 3e-13 m of rim


def quantisation_bound(spec, distance: float) -> float:
    """|position error| of encoder odometry along a straight path of `distance` m: every wheel's running
    tick count lags the truth by less than one tick (carry), so the summed twist lags by at most
    B = Σ_i |pinv(A)_ki| r_i cos γ_i · 2π/ticks per component k; the heading error ≤ B_ω tilts
    the path, adding ≤ B_ω·distance; 10 % for the second-order terms of small angles."""
    c = spec.chassis.chassis
    from sim.kinematics.chassis import forward_pinv, forward_system

    a, _ = forward_system(c, np.zeros(c.n), c.beta)
    per_tick = np.abs(forward_pinv(a)[:, : c.n]) @ (c.radius * np.cos(c.gamma)) * 2 * np.pi / spec.encoders.ticks_per_rev
    return 1.1 * (math.hypot(per_tick[0], per_tick[1]) + per_tick[2] * distance)


@pytest.mark.parametrize("name", sorted(ODOMETRY_ROBOTS))
def test_encoder_odometry_stays_within_the_derived_quantisation_bound(name):
    spec = ODOMETRY_ROBOTS[name].with_changes(motor=FAST)
    result = run(EMPTY, [RobotSetup(spec, constant(Twist(0.3, 0.0)))], 4.0)
    log = result.robots[0]
    truth = log.truth_array()
    error = np.linalg.norm(log.estimate_arrays()["encoders"][:, :2] - truth[:, :2], axis=1)
    distance = np.linalg.norm(truth[-1, :2] - truth[0, :2])
    assert 1e-6 < error.max() <= quantisation_bound(spec, distance)


def test_wheels_commanded_against_each_other_slip_and_the_encoders_see_it():
    """Rear wheels that disagree with the steering: the world's least squares leaves a residual (slip);
    the encoders of all four wheels measure exactly that misfit, and the pose stays exact because the
    robot's least squares is the world's."""
    spec = CAR.with_changes(encoders=FINE, motor=FAST)
    beta = spec.chassis.chassis.beta

    def drive(phi_dot):
        world = World(EMPTY, dt=DT)
        world.add_robot(spec)
        odometry = ChassisEncoderOdometry()
        odometry.reset(spec, world.poses()[0])
        for _ in range(100):
            world.chassis.command(0, phi_dot, beta)
            world.step(np.zeros((1, 2)))
            odometry.update(world.read_all()[0])
        error = np.linalg.norm(odometry.pose[:2] - world.poses()[0, :2])
        return world.chassis.drives[0].slip * DT, odometry.residual, error

    slip, residual, error = drive(np.array([0.0, 0.0, 6.0, 6.0]))
    assert slip < 1e-12 and residual < 1e-9 and error < 1e-9
    slip, residual, error = drive(np.array([0.0, 0.0, 4.0, 8.0]))
    assert slip > 1e-4 and residual == pytest.approx(slip, rel=1e-6)  # 1e-11 rad ticks against 1e-3 m
    assert error < 1e-9


def test_random_wheel_slip_shows_as_encoder_error():
    spec = MECANUM4.with_changes(encoders=EncoderSpec(ticks_per_rev=2**40, slip_std=0.05), motor=FAST)
    log = run(EMPTY, [RobotSetup(spec, constant(Twist(0.3, 0.2, vy=0.2)))], 2.0).robots[0]
    assert np.linalg.norm(log.estimate_arrays()["encoders"][-1, :2] - log.truth_array()[-1, :2]) > 1e-3


def test_two_mice_see_an_omni_robot_exactly_and_one_mouse_is_refused():
    spec = MECANUM4.with_changes(mouse={"dpi": 1e12}, chassis={"mouse2": MouseSpec((-0.1, 0.08), dpi=1e12)}, motor=FAST)
    log = run(EMPTY, [RobotSetup(spec, constant(Twist(0.3, 0.4, vy=0.2)))], 2.0).robots[0]
    assert np.abs(log.estimate_arrays()["mouse"] - log.truth_array()).max() < 1e-9  # 2.5e-14 m per count
    one = MECANUM4.with_changes(chassis={"mouse2": None})
    assert not mouse_applies(one)
    with pytest.raises(ValueError, match="add a second mouse"):
        ChassisMouseOdometry().reset(one, np.zeros(3))
    assert mouse_applies(CAR)  # one mouse and the rear axle's constraint


def test_a_polygon_robot_stops_at_a_wall_without_tunnelling_and_slides_along_it():
    wall = Wall(box(1.0, -2.0, 1.02, 2.0))
    world = WorldSpec("wall", (-3, -3, 3, 3), walls=(wall,), starts=(Start(0.0, 0.0, 0.3),))
    result = run(world, [RobotSetup(MECANUM4, constant(Twist(1.0, 0.0, vy=0.3)))], 3.0)
    truth = result.robots[0].truth_array()
    corners = np.array(MECANUM4.chassis.outline)
    for x, _y, th in truth:
        world_x = x + np.cos(th) * corners[:, 0] - np.sin(th) * corners[:, 1]
        assert world_x.max() < 1.0 + 0.02  # never through the 2 cm wall; pymunk's contact depth is mm
    assert truth[-1, 1] - truth[0, 1] > 0.3  # slid along it


def test_command_and_fault_errors_are_clear():
    readings = Readings(steering=MECANUM4.chassis.chassis.beta)
    with pytest.raises(InfeasibleCommand, match="slide sideways"):
        chassis_setpoints(Twist(0.0, 0.0, vy=0.2), REFUSING_CAR, Readings(steering=CAR.chassis.chassis.beta))
    with pytest.raises(ValueError, match="4 speeds"):
        chassis_setpoints(WheelCommands((1.0, 2.0)), MECANUM4, readings)
    world = World(EMPTY)
    world.add_robot(MECANUM4)
    with pytest.raises(ValueError, match="not steered"):
        world.chassis.fail(0, 1, "steering")


def test_robot_files_name_a_preset_or_list_wheels(tmp_path):
    preset = tmp_path / "m.toml"
    preset.write_text('name = "m"\nmass = 4.0\n[chassis]\npreset = "mecanum4"\nwheelbase = 0.5\n'
                      'outline = [[0.3, -0.2], [0.3, 0.2], [-0.3, 0.2], [-0.3, -0.2]]\ninfeasible = "project"\n')
    spec = load_robot(preset)
    assert spec.chassis.chassis.n == 4 and spec.body_radius == pytest.approx(0.2)
    wheels = tmp_path / "w.toml"
    wheels.write_text('name = "w"\nbody_radius = 0.3\n[chassis]\n'
                      '[[chassis.wheels]]\ntype = "steered"\nx = 0.2\ny = 0.0\nradius = 0.05\n'
                      '[[chassis.wheels]]\ntype = "fixed"\nx = 0.0\ny = 0.15\nradius = 0.05\ndriven = false\n'
                      '[[chassis.wheels]]\ntype = "fixed"\nx = 0.0\ny = -0.15\nradius = 0.05\ndriven = false\n')
    assert load_robot(wheels).chassis.chassis.kind.tolist() == [1, 0, 0]
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "b"\nbody_radius = 0.3\n[chassis]\npreset = "hovercraft"\n')
    with pytest.raises(ValueError, match=r"bad.toml:3: \[chassis\]: unknown preset 'hovercraft'"):
        load_robot(bad)
    wheel = tmp_path / "wheel.toml"
    wheel.write_text('name = "b"\nbody_radius = 0.3\n[chassis]\n[[chassis.wheels]]\ntype = "omni"\nx = 0.1\ny = 0\nradus = 1\n')
    with pytest.raises(ValueError, match=r"\[\[wheels\]\] #1: unknown key\(s\) radus"):
        load_robot(wheel)


def test_the_inverse_kinematics_the_run_uses_is_the_cores():
    readings = Readings(steering=MECANUM4.chassis.chassis.beta)
    setpoint = chassis_setpoints(Twist(0.2, 0.1, vy=-0.1), MECANUM4, readings)
    assert_allclose(setpoint.phi_dot, inverse_kinematics(MECANUM4.chassis.chassis, [0.2, -0.1, 0.1]).phi_dot)
    assert_allclose(nearest_feasible(MECANUM4.chassis.chassis, setpoint.twist), setpoint.twist)


def test_the_drawn_icr_is_the_fixed_point_of_the_step_and_wheels_sit_on_the_body():
    from sim.views.chassis_view import chassis_shapes

    previous = np.array([1.0, 2.0, 0.3])
    centre = np.array([1.5, 2.7])  # rotate the body about this point by 0.2 rad
    c, s = np.cos(0.2), np.sin(0.2)
    position = centre + np.array([[c, -s], [s, c]]) @ (previous[:2] - centre)
    pose = np.array([*position, 0.5])
    shapes = chassis_shapes(CAR, pose, CAR.chassis.chassis.beta, previous, (-10, -10, 10, 10))
    assert_allclose(shapes.icr, centre, atol=1e-12)
    assert_allclose(shapes.wheels.mean(axis=1), CAR.chassis.chassis.positions @ np.array([[np.cos(0.5), np.sin(0.5)], [-np.sin(0.5), np.cos(0.5)]]) + pose[:2], atol=1e-12)
    assert chassis_shapes(CAR, pose, CAR.chassis.chassis.beta, previous, (-1, -1, 0, 0)).icr is None


def test_a_recording_of_a_chassis_robot_holds_wheels_outline_and_icr(tmp_path):
    import rerun.chunk

    from sim.views.chassis_view import body_outline
    from sim.views.recording.recorder import Recorder

    path = tmp_path / "run.rrd"
    result = run(EMPTY, [RobotSetup(CAR, constant(Twist(0.3, 0.2)))], 2.0, observers=(Recorder(path),))
    rows: dict[str, list[tuple[float, dict]]] = {}  # entity -> (time s, -1 static; row) in time order
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        for row in chunk.to_record_batch().to_pylist():
            time = row["sim_time"].total_seconds() if "sim_time" in row else -1.0
            rows.setdefault(str(chunk.entity_path), []).append((time, row))
    last = {entity: sorted(entries, key=lambda entry: entry[0])[-1][1] for entity, entries in rows.items()}
    # the outline is the chassis's polygon, static in the body frame: it moves with the true pose
    outline = np.array(last["/world/car/body/outline"]["LineStrips2D:strips"][0])
    assert_allclose(outline, body_outline(CAR), atol=1e-6)  # float32 storage
    # one encoder series per wheel, one steering series per steered wheel
    assert len(last["/sensors/encoders/car/encoder_ticks"]["Scalars:scalars"]) == 4
    steered = np.degrees(wrap_angle(result.robots[0].latest.steering - CAR.chassis.chassis.beta))[:2]  # from straight
    assert_allclose(last["/sensors/steering/car/steering"]["Scalars:scalars"], steered, atol=1e-9)  # float64 series
    # wheels in the body frame, drawn again as the steering turns: the last ones at the final angles
    origins, vectors = (np.array(last["/world/car/body/wheels"][f"Arrows2D:{f}"]) for f in ("origins", "vectors"))
    c = CAR.chassis.chassis
    assert_allclose(origins + 0.5 * vectors, c.positions, atol=1e-6)  # float32 in the recording
    heading = c.alpha + result.robots[0].latest.steering - np.pi / 2  # steering settled long before the end
    assert_allclose(vectors, 2 * c.radius[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1), atol=1e-6)
    # the last ICR: v/ω = 1.5 m to the left of the rear axle's middle, where the last pose puts it
    icr = sorted(rows["/world/car/chassis/icr"], key=lambda entry: entry[0])[-1]
    pose = result.robots[0].truth_array()[round(icr[0] / DT)]
    assert_allclose(icr[1]["Points2D:positions"][0], pose[:2] + 1.5 * np.array([-np.sin(pose[2]), np.cos(pose[2])]), atol=1e-5)  # float32 (of 1.5 m)


def test_a_recorded_wheel_fault_is_an_event_and_turns_the_wheel_red(tmp_path):
    import rerun.chunk

    from sim.views import palette
    from sim.views.recording.recorder import Recorder

    path = tmp_path / "run.rrd"
    setup = RobotSetup(MECANUM4, constant(Twist(0.2, 0.3)), faults=(WheelFault(0.2, 1, "free"),))
    run(EMPTY, [setup], 0.5, observers=(Recorder(path),))
    rows = {}
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        for row in chunk.to_record_batch().to_pylist():
            rows.setdefault(str(chunk.entity_path), []).append(row)
    events = [row["TextLog:text"][0] for row in rows["/events"]]
    assert any("mecanum4: front right rolls free" in text for text in events), events
    wheels = sorted((row["sim_time"], row["Arrows2D:colors"]) for row in rows["/world/mecanum4/body/wheels"] if "sim_time" in row)
    red, black = (int.from_bytes(bytes([*rgb, 255]), "big") for rgb in (palette.FAULT, palette.WHEEL))  # rerun's packed RGBA
    assert wheels[0][1] == [black] * 4 and wheels[-1][1] == [black, red, black, black]


def test_follow_path_ocp_drives_a_mecanum_robot_through_a_path_and_refuses_a_ctbot():
    from bots.behaviours import FollowPathOCP
    from bots.controller import Status
    from bots.ctbot import CTBOT

    follower = FollowPathOCP("1,0;1,1", speed=0.5, lookahead_m=0.3)
    start = WorldSpec("empty", (-5, -5, 5, 5), starts=(Start(0.0, 0.0, 0.0),))
    result = run(start, [RobotSetup(MECANUM4, follower)], 8.0)
    truth = result.robots[0].truth_array()
    assert follower.status is Status.SUCCESS
    assert np.hypot(*(truth[-1, :2] - [1.0, 1.0])) < 0.03  # ARRIVED (2 cm, by odometry) + encoder drift
    off_path = np.minimum(np.abs(truth[:, 1]) + np.maximum(truth[:, 0] - 1, 0), np.abs(truth[:, 0] - 1))
    assert off_path.max() < 0.2  # corner cut by at most about the look-ahead
    with pytest.raises(ValueError, match="differential drive"):
        FollowPathOCP().reset(CTBOT)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_the_compiled_wheel_step_is_the_cores_forward_kinematics_motor_and_encoders(name):
    """`chassis_drive._wheels` against the core's functions: the motor model, the least-squares twist
    and its residual (`forward_kinematics`), rolling of an unmeasured (free) wheel, the encoders
    (`quantize`) and the exact step (`se2_exp`)."""
    from sim.kinematics import quantize
    from sim.kinematics.chassis import forward_pinv, forward_system, rolling_rows
    from sim.world.chassis_drive import Motors, Solver, Wheels, _wheels

    chassis = PRESETS[name]()
    n, rng = chassis.n, np.random.default_rng(15)
    degraded = degrade(chassis, Failure(0, drive=True)) if chassis.driven.sum() > 1 else chassis
    measured = degraded.driven | degraded.locked
    beta = chassis.beta + rng.uniform(-0.2, 0.2, n) * (chassis.kind == WheelType.STEERED)  # steered somewhere
    a, _ = forward_system(degraded, np.zeros(n), beta, measured)
    rolls = rolling_rows(degraded.alpha, beta, degraded.l, degraded.gamma)
    rim = degraded.radius * np.cos(degraded.gamma)
    phi, target, top = rng.uniform(-5, 5, n), rng.uniform(-20, 20, n), np.full(n, 12.0)
    slip, carry = rng.normal(0, 0.05, n), rng.uniform(0, 1, n)
    lag, max_change, dt, ticks_per_rad = 0.3, 1.5, 0.01, 60 / (2 * np.pi)

    phi_dot, tick_carry, ticks, twist = phi.copy(), carry.copy(), np.zeros(n, dtype=np.int64), np.zeros(3)
    *increment, residual = _wheels(dt, Motors(top, lag, max_change, ticks_per_rad), Wheels(phi_dot, target, degraded.driven, degraded.locked, measured, rim, slip),
                                   Solver(a, forward_pinv(a), rolls), tick_carry, ticks, twist)

    expected = np.where(degraded.driven, phi + np.clip((np.clip(target, -top, top) - phi) * lag, -max_change, max_change), phi)
    slipped = expected + slip * np.sqrt(np.abs(expected * rim) / dt) / rim  # the arc off by slip * sqrt(|arc|)
    solution = forward_kinematics(degraded, slipped, beta, measured=measured)
    assert_allclose(twist, solution.twist, atol=1e-12)  # the same pinv, summed in another order
    assert residual == pytest.approx(float(solution.slip), abs=1e-12)
    expected = np.where(measured, expected, rolls @ solution.twist / rim)  # the free wheel rolls with the body
    assert_allclose(phi_dot, expected, atol=1e-12)
    counts, rest = quantize(expected * dt * ticks_per_rad, carry)
    assert_array_equal(ticks, counts)
    assert_allclose(tick_carry, rest, atol=1e-12)
    assert_allclose(increment, se2_exp(solution.twist * dt), atol=1e-15)


@pytest.mark.parametrize("name", sorted(WHEELED_ROBOTS))
def test_the_path_follower_drives_on_after_the_yards_wheel_fault(name):
    """The shipped yard frees a wheel at 20 s: every shipped chassis keeps following the path with
    what the core still calls feasible (an omni robot that can only move along a skewed line
    drives along that line) instead of stopping with an infeasible command."""
    from bots.behaviours import make
    from sim.world.files import load_world

    result = run(load_world("chassis_yard"), [RobotSetup(WHEELED_ROBOTS[name], make("follow_path_ocp"))], 24.0)
    # a robot may finish the path before 24 s ('done'), never give it up nor fail (the car may scrape
    # the yard's tight corners)
    assert result.reason in ("duration", "done"), result.error
    assert result.robots[0].status != "failure"


def test_the_live_stream_gets_every_entity_of_the_file_and_the_projection_note(tmp_path):
    """Outline, wheels and ICR of a chassis robot (and everything else) go to every stream, not only
    the file; a projected command's note reaches the events of both."""
    import rerun.chunk
    from observers import FakeLive

    path = tmp_path / "run.rrd"
    live = FakeLive()
    result = run(EMPTY, [RobotSetup(CAR, constant(Twist(0.3, 2.0)))], 1.0, observers=(live.recorder(path),))
    assert result.reason == "duration" and result.robots[0].notes
    in_file: set[str] = set()
    events = []
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        in_file.add(str(chunk.entity_path))
        if str(chunk.entity_path) == "/events":
            events += [row["TextLog:text"][0] for row in chunk.to_record_batch().to_pylist()]
    assert {"/world/car/body/outline", "/world/car/body/wheels", "/world/car/chassis/icr"} <= in_file
    assert in_file == live.paths
    notes = [text for text in events if "car: note: step" in text and "beyond the steering limits" in text]
    assert len(notes) == 1 and notes[0] in live.events  # the first of its kind, once
