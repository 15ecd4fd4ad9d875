"""The general chassis kinematics against every numeric example of Köb (2005), chassis-koeb-thesis.md §3."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from printed import places

from sim.kinematics import chassis_presets as presets
from sim.kinematics import wrap_angle
from sim.kinematics.chassis import (
    Chassis,
    Failure,
    InfeasibleTwist,
    Wheel,
    WheelType,
    allocate_torques,
    allocation_matrix,
    degrade,
    forward_kinematics,
    icr,
    icr_locus,
    inverse_kinematics,
    is_feasible,
    mobility,
    motion_subspaces,
    projector,
    qualitative_matrices,
    radius_matrix,
    rolling_matrix,
    sliding_matrix,
    to_body,
    to_world,
    twist_from_icr,
)

DEG = np.pi / 180


def same_span(basis, expected):
    """Subspaces are compared as spans (thesis §5.16), through their orthogonal projectors."""
    assert_allclose(projector(basis), projector(np.array(expected, dtype=float).reshape(-1, 3).T), atol=1e-9)


def failed_drives(chassis, *wheels):
    return degrade(chassis, *(Failure(w, drive=True) for w in wheels))


ATOL = places(6)


def equivalent_settings(beta, speed, beta_ref, speed_ref, atol=ATOL):
    """(β, v) and (β + π, −v) are the same wheel setting (thesis §5.11)."""
    beta, speed = np.asarray(beta), np.asarray(speed)
    same = np.isclose(wrap_angle(beta - beta_ref), 0, atol=atol) & np.isclose(speed, speed_ref, atol=atol)
    flipped = np.isclose(wrap_angle(beta - beta_ref - np.pi), 0, atol=atol) & np.isclose(speed, -speed_ref, atol=atol)
    return bool(np.all(same | flipped))


# --- §3.1 kinetic torque allocation, old RoboCup chassis ---------------------------------------------

OMNI4 = presets.omni4()


def test_allocation_matrix_all_drives():
    a = allocation_matrix(OMNI4)
    assert_allclose(a, [[0, 50, 0, -50], [-50, 0, 50, 0], [-10, -10, -10, -10]], atol=1e-12)
    assert_allclose(np.linalg.pinv(a), np.array([[0, -10, -25], [10, 0, -25], [0, 10, -25], [-10, 0, -25]]) * 1e-3,
                    atol=1e-12)
    # erratum 1: the printed (AᵀA)⁻¹Aᵀ cannot be formed, AᵀA is singular
    assert np.linalg.matrix_rank(a.T @ a) == 3  # 4×4 of rank 3


@pytest.mark.parametrize("wrench, torques", [
    ([1, 0, 0], [0, 10, 0, -10]),
    ([0, 0, -1], [25, 25, 25, 25]),
    ([1, 1, 0], [-10, 10, 10, -10]),
    ([0, 1, 0], [-10, 0, 10, 0]),
])
def test_allocation_all_drives_exact(wrench, torques):
    result = allocate_torques(OMNI4, wrench)
    assert result.rank == 3
    assert_allclose(result.torques, np.array(torques) * 1e-3, atol=1e-12)
    assert_allclose(result.achieved, wrench, atol=1e-12)


def test_allocation_drive_4_failed():
    chassis = failed_drives(OMNI4, 3)
    assert_allclose(np.linalg.pinv(allocation_matrix(chassis)),
                    np.array([[-10, -10, -50], [20, 0, 0], [-10, 10, -50], [0, 0, 0]]) * 1e-3, atol=1e-12)
    result = allocate_torques(chassis, [[1, 0, 0], [0, 0, -1]])
    assert result.rank == 3
    assert_allclose(result.torques, np.array([[-10, 20, -10, 0], [50, 0, 50, 0]]) * 1e-3, atol=1e-12)


def test_allocation_drives_3_and_4_failed_least_squares_with_erratum():
    chassis = failed_drives(OMNI4, 2, 3)
    assert_allclose(np.linalg.pinv(allocation_matrix(chassis))[:2],
                    [[-1 / 1350, -13 / 675, -1 / 270], [13 / 675, 1 / 1350, -1 / 270]], atol=1e-15)
    result = allocate_torques(chassis, [[1, 0, 0], [0, 0, -1], [1, 1, 0]])
    assert result.rank == 2
    assert_allclose(result.torques[0], [-1 / 1350, 13 / 675, 0, 0], atol=1e-15)
    assert_allclose(result.achieved[0], [26 / 27, 1 / 27, -5 / 27], atol=1e-12)
    # erratum 2: the thesis prints the opposite signs for F_R = [0, 0, −1]
    assert_allclose(result.torques[1], [1 / 270, 1 / 270, 0, 0], atol=1e-15)
    assert_allclose(result.achieved[1], [5 / 27, -5 / 27, -2 / 27], atol=1e-12)
    # the first median is still feasible and reproduced exactly
    assert_allclose(result.torques[2], [-1 / 50, 1 / 50, 0, 0], atol=1e-15)
    assert_allclose(result.achieved[2], [1, 1, 0], atol=1e-12)
    assert_allclose(result.residual, [np.linalg.norm(np.subtract([1, 0, 0], result.achieved[0])),
                                      np.linalg.norm(np.subtract([0, 0, -1], result.achieved[1])), 0], atol=1e-12)


def test_allocation_drives_2_and_4_failed_and_only_drive_1():
    result = allocate_torques(failed_drives(OMNI4, 1, 3), [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    assert result.rank == 2
    assert_allclose(result.torques, np.array([[0, 0, 0, 0], [50, 0, 50, 0], [-10, 0, 10, 0]]) * 1e-3, atol=1e-12)
    only_1 = allocate_torques(failed_drives(OMNI4, 1, 2, 3), [0, 0, -1])
    assert only_1.rank == 1
    assert_allclose(only_1.torques, [10 / 2600, 0, 0, 0], atol=1e-15)
    assert_allclose(only_1.achieved, [0, -0.1923077, -0.0384615], atol=places(7))


def test_allocation_refuses_constrained_chassis():
    with pytest.raises(ValueError, match="without fixed or steered"):
        allocation_matrix(presets.differential_drive())


def test_duality_allocation_is_wheel_jacobian_transposed_also_for_mecanum():
    """(2.81), proved in §2.10: J₂⁻¹J₁ = Aᵀ, with J₂ = diag(r cos γ) for γ ≠ 0."""
    for chassis in (OMNI4, presets.omni3(), presets.mecanum4()):
        assert_allclose(np.linalg.solve(radius_matrix(chassis), rolling_matrix(chassis)), allocation_matrix(chassis).T,
                        atol=1e-12)


def test_power_balance_of_allocation():
    """Virtual power: φ̇ᵀM = ξ̇ᵀF_R for the allocated torques of a fully actuated chassis."""
    chassis, twist, wrench = presets.mecanum4(), np.array([0.3, -0.2, 0.7]), np.array([2.0, 1.0, -0.5])
    torques = allocate_torques(chassis, wrench).torques
    assert np.dot(inverse_kinematics(chassis, twist).phi_dot, torques) == pytest.approx(twist @ wrench)


# --- §3.2 differential drive -----------------------------------------------------------------------------


def test_differential_drive_matrices_and_kernel():
    chassis = presets.differential_drive(track=0.2, wheel_radius=0.02)
    assert_allclose(rolling_matrix(chassis), [[1, 0, -0.1], [1, 0, 0.1]], atol=1e-15)
    assert_allclose(np.abs(sliding_matrix(chassis)), [[0, 1, 0], [0, 1, 0]], atol=1e-15)  # erratum 7: signs
    same_span(motion_subspaces(chassis).Z, [[1, 0, 0], [0, 0, 1]])  # (2.65)
    locus = icr_locus(chassis)
    assert locus.kind == "line" and abs(locus.offset) < 1e-15
    assert_allclose(np.abs(locus.normal), [1, 0], atol=1e-15)  # x_R = 0


@pytest.mark.parametrize("twist, phi_dot, icr_h", [
    ((0.2, 0, 0), (10, 10), (0, 0.2, 0)),
    ((0, 0, 1), (-5, 5), (0, 0, 1)),
    ((0.2, 0, 1), (5, 15), (0, 0.2, 1)),
])
def test_differential_drive_wheel_speeds(twist, phi_dot, icr_h):
    chassis = presets.differential_drive(track=0.2, wheel_radius=0.02)
    assert_allclose(inverse_kinematics(chassis, twist).phi_dot, phi_dot, atol=1e-12)
    assert_allclose(icr(twist), icr_h, atol=1e-15)


# --- §3.3 four omni wheels, kinematic method ---------------------------------------------------------------


def test_omni4_constraint_matrices():
    j1 = rolling_matrix(OMNI4)
    assert_allclose(j1, [[0, -1, -0.2], [1, 0, -0.2], [0, 1, -0.2], [-1, 0, -0.2]], atol=1e-15)
    assert_allclose(radius_matrix(OMNI4), 0.02 * np.eye(4))
    assert_allclose(np.linalg.solve(radius_matrix(OMNI4), j1),
                    [[0, -50, -10], [50, 0, -10], [0, 50, -10], [-50, 0, -10]], atol=1e-12)
    assert not sliding_matrix(OMNI4).any()


@pytest.mark.parametrize("failed", [(), (0,), (3,)])
def test_omni4_full_mobility_with_at_most_one_failed_drive(failed):
    spaces = motion_subspaces(failed_drives(OMNI4, *failed))
    same_span(spaces.B, np.eye(3))
    assert spaces.sbar.shape == (3, 0) and spaces.D.shape == (3, 0)


def test_omni4_drives_3_and_4_failed_subspaces():
    spaces = motion_subspaces(failed_drives(OMNI4, 2, 3))
    same_span(spaces.Z, np.eye(3))
    same_span(spaces.sbar, [0.2, -0.2, 1])
    same_span(spaces.S, [[1, 1, 0], [-5, 0, 1]])
    same_span(spaces.B, [[1, 0, -0.2], [0, 1, 0.2]])
    same_span(spaces.B, [[0, 5, 1], [1, 1, 0]])  # the "readable" basis names the same space
    same_span(spaces.D, [1, -1, 5])


# --- §3.4 three steered wheels ------------------------------------------------------------------------------

STEERED3 = presets.steered3()
S3 = 0.8660254037844386


def test_steered3_case1_all_ok():
    j1q, c1q = qualitative_matrices(STEERED3)
    assert_allclose(j1q, [[0, -1, -0.2], [1, 0, 0], [S3, 0.5, -0.2], [-0.5, S3, 0], [-S3, 0.5, -0.2],
                          [-0.5, -S3, 0]], atol=1e-12)
    assert not c1q.any()
    spaces = motion_subspaces(STEERED3)
    same_span(spaces.B, np.eye(3))
    assert spaces.sbar.shape[1] == 0 and spaces.D.shape[1] == 0


def test_steered3_case2_frozen_steering():
    chassis = degrade(STEERED3, Failure(2, steering=True, frozen_beta=30 * DEG))
    j1q, c1q = qualitative_matrices(chassis)
    assert_allclose(c1q, [[0, 0, 0], [0, 0, 0], [0, -1, 0.1]], atol=1e-12)
    assert_allclose(j1q[-1], [-1, 0, -0.2 * S3], atol=1e-12)  # erratum 13: −0.173, not +0.173
    spaces = motion_subspaces(chassis)
    same_span(spaces.Z, [[1, 0, 0], [0, 0.1, 1]])
    same_span(spaces.B, [[1, 0, 0], [0, 0.1, 1]])
    assert spaces.D.shape[1] == 0
    locus = icr_locus(chassis)  # the ICR lies on wheel 3's axle x_R = −0.1; the thesis criterion says "unique"
    assert locus.kind == "line"
    assert_allclose(locus.normal * locus.offset / np.dot(locus.normal, locus.normal), [-0.1, 0], atol=1e-12)


def test_steered3_case3_one_failed_drive():
    spaces = motion_subspaces(failed_drives(STEERED3, 2))
    same_span(spaces.B, np.eye(3))


def test_steered3_case4_two_failed_drives():
    chassis = failed_drives(STEERED3, 1, 2)
    j1q, _ = qualitative_matrices(chassis)
    assert_allclose(j1q, [[0, -1, -0.2], [1, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]], atol=1e-12)
    spaces = motion_subspaces(chassis)
    same_span(spaces.sbar, [0, -0.2, 1])
    same_span(spaces.B, [[0, 5, 1], [1, 0, 0]])
    same_span(spaces.D, [0, -0.2, 1])  # rotation about wheel 1's contact point


def test_steered3_case5_two_frozen_one_failed():
    chassis = degrade(STEERED3, Failure(0, steering=True, frozen_beta=30 * DEG), Failure(1, drive=True),
                      Failure(2, steering=True, frozen_beta=-30 * DEG))
    j1q, c1q = qualitative_matrices(chassis)
    assert_allclose(c1q, [[S3, 0.5, 0.1], [0, 0, 0], [-S3, -0.5, -0.1]], atol=1e-12)
    assert_allclose(j1q, [[0.5, -S3, -0.2 * S3], [0, 0, 0], [0, 0, 0], [-0.5, S3, -0.2 * S3]], atol=1e-12)
    spaces = motion_subspaces(chassis)
    same_span(spaces.Z, [[-1 / np.sqrt(3), 1, 0], [-0.1 / S3, 0, 1]])  # thesis: −0.577, −0.116 (= −0.11547)
    same_span(spaces.B, [[-1 / np.sqrt(3), 1, 0], [-0.1 / S3, 0, 1]])
    same_span(spaces.sbar, [np.sqrt(3), 1, 0])
    assert spaces.D.shape[1] == 0
    # differential-drive-like axle plus a steered wheel that can still turn: a tricycle (δ_m = 1, δ_s = 1)
    assert mobility(chassis) == mobility(presets.tricycle())


# --- refusal of infeasible commands -------------------------------------------------------------------------


def test_command_outside_b_is_refused_with_nearest_twist():
    chassis = failed_drives(OMNI4, 2, 3)
    with pytest.raises(InfeasibleTwist, match="uncontrollable") as info:
        inverse_kinematics(chassis, [0.0, 0.0, 1.0])
    b = projector(motion_subspaces(chassis).B)
    assert_allclose(info.value.nearest, b @ [0, 0, 1], atol=1e-12)
    assert is_feasible(chassis, info.value.nearest)
    assert_allclose(inverse_kinematics(chassis, [1, 1, 0]).phi_dot[:2], [-50, 50], atol=1e-9)  # first median


def test_sliding_violation_names_the_wheels_and_batch_mask():
    chassis = presets.differential_drive()
    twists = np.array([[0.1, 0.0, 0.5], [0.1, 0.05, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(InfeasibleTwist, match="left, right slide sideways") as info:
        inverse_kinematics(chassis, twists)
    assert info.value.mask.tolist() == [False, True, False]
    assert_allclose(info.value.nearest, [[0.1, 0, 0.5], [0.1, 0, 0], [0, 0, 1]], atol=1e-12)
    assert isinstance(info.value, ValueError)


def test_degraded_steered_chassis_refuses_twist_off_the_frozen_axle():
    chassis = degrade(STEERED3, Failure(2, steering=True, frozen_beta=30 * DEG))
    inverse_kinematics(chassis, [0.7, 0.1, 1.0])  # ICR (−0.1, 0.7) on wheel 3's axle
    with pytest.raises(InfeasibleTwist, match="wheel 3 slide"):
        inverse_kinematics(chassis, [0.0, 0.0, 1.0])


# --- §3.6 inverse kinematics on the three-steered chassis ---------------------------------------------------


@pytest.mark.parametrize("twist, beta_deg, speed", [
    ((1, 0, 0), (90, -30, -150), (1, 1, 1)),
    ((0, 1, 0), (180, 60, -60), (1, 1, 1)),
    ((0, 0, 1), (180, 180, 180), (0.2, 0.2, 0.2)),
    ((1, 0, 1), (101.310, -36.896, -154.872), (1.0198, 0.8328, 1.1775)),
    ((0.5, 0.2, -0.8), (-85.426, 173.677, 67.765), (-0.5016, -0.6973, -0.4572)),
    ((0, 0.1, 1), (180, 150, -150), (0.3, 0.1732, 0.1732)),
])
def test_steered3_steering_and_speeds(twist, beta_deg, speed):
    for branch in ("nearest", "forward"):
        cmd = inverse_kinematics(STEERED3, twist, branch=branch)
        assert equivalent_settings(cmd.beta, cmd.rim_speed, np.radians(beta_deg), np.array(speed), atol=places(3) / 2)  # the thesis prints degrees with three decimals and speeds with four
        assert_allclose(cmd.phi_dot, cmd.rim_speed / 0.02)
    assert (inverse_kinematics(STEERED3, twist, branch="forward").rim_speed >= 0).all()


def test_steered3_rpm():
    cmd = inverse_kinematics(STEERED3, [1.0, 0.0, 0.0])
    assert_allclose(cmd.phi_dot, 50)
    assert_allclose(cmd.rpm, 477.46, atol=places(2) / 2)
    assert_allclose(np.abs(inverse_kinematics(STEERED3, [0, 0, 1.0]).rpm), 95.49, atol=places(2) / 2)


def test_icr_on_a_wheel_keeps_its_steering():
    previous = np.array([0.3, 0.0, 0.0])
    cmd = inverse_kinematics(STEERED3, [0.0, -0.2, 1.0], previous_beta=previous)
    assert cmd.at_icr.tolist() == [True, False, False]
    assert cmd.beta[0] == 0.3 and cmd.phi_dot[0] == 0.0


def test_zero_twist_keeps_steering_and_stops():
    cmd = inverse_kinematics(STEERED3, np.zeros(3))
    assert_allclose(cmd.beta, STEERED3.beta)
    assert not cmd.phi_dot.any()


def test_pi_flip_pairs_with_sign_change():
    """Through ω = 0 the ICR method jumps to (β + π, −v); the nearest branch stays continuous instead."""
    up = inverse_kinematics(STEERED3, [1.0, 0.0, 1e-3], branch="forward")
    down = inverse_kinematics(STEERED3, [1.0, 0.0, -1e-3], branch="forward")
    assert_allclose(np.degrees(up.beta[1]), -30.0057, atol=places(4))
    assert_allclose(up.rim_speed[1], 0.99983, atol=places(5))
    assert equivalent_settings(down.beta[1], down.rim_speed[1], 150.0057 * DEG, -1.00017, atol=places(4) / 10)
    nearest = inverse_kinematics(STEERED3, [1.0, 0.0, -1e-3], previous_beta=up.beta)
    assert abs(wrap_angle(nearest.beta[1] - up.beta[1])) < 1e-3
    flipped = inverse_kinematics(STEERED3, [1.0, 0.0, -1e-3], previous_beta=up.beta + np.pi)
    assert_allclose(flipped.rim_speed, -nearest.rim_speed)
    assert_allclose(wrap_angle(flipped.beta - nearest.beta - np.pi), 0, atol=1e-12)


@pytest.mark.parametrize("twist, phi_dot", [((1, 0, 0), (0, 50, 0, -50)), ((0, 0, 1), (-10, -10, -10, -10))])
def test_omni4_inverse_kinematics(twist, phi_dot):
    assert_allclose(inverse_kinematics(OMNI4, twist).phi_dot, phi_dot, atol=1e-12)


def test_omni_formula_2_116_equals_rolling_rows():
    """(2.116): φ̇ = v cos(β_req − β′ − γ)/(r cos γ) with the ICR method's β_req, for γ = 0, 45°, −30°."""
    rng = np.random.default_rng(1)
    for gamma in (0.0, np.pi / 4, -np.pi / 6):
        wheel = Wheel(WheelType.OMNI, 0.3, 0.4, 0.2, 0.05, gamma=gamma)
        chassis = Chassis.from_wheels([wheel, Wheel(WheelType.OMNI, 0.3, 2.5, -0.3, 0.05),
                                       Wheel(WheelType.OMNI, 0.3, -1.9, 0.1, 0.05)])
        twist = rng.normal(size=(20, 3))
        v_a = twist[:, :2] + twist[:, 2:] * np.array([-np.sin(0.4), np.cos(0.4)]) * 0.3
        beta_req = np.arctan2(v_a[:, 0], -v_a[:, 1]) - 0.4
        expected = np.hypot(*v_a.T) * np.cos(beta_req - 0.2 - gamma) / (0.05 * np.cos(gamma))
        assert_allclose(inverse_kinematics(chassis, twist).phi_dot[:, 0], expected, atol=1e-10)


def test_castor_swivels_by_its_sliding_constraint():
    """(2.51): c·ξ + dβ̇ = 0 means the contact point B = A + d·u of the castor does not slide sideways."""
    castor = Wheel(WheelType.CASTOR, 0.25, 2.0, 0.7, 0.03, offset=0.04, driven=False)
    chassis = Chassis.from_wheels([castor, *(Wheel(WheelType.OMNI, 0.2, a, 0.0, 0.02) for a in (0, 2.1, -2.1))])
    twist = np.array([0.3, -0.1, 0.8])
    cmd = inverse_kinematics(chassis, twist)
    rolling = np.array([np.sin(2.7), -np.cos(2.7)])
    axle = np.array([np.cos(2.7), np.sin(2.7)])
    pivot = chassis.positions[0]
    contact = pivot + 0.04 * rolling
    v_pivot = twist[:2] + twist[2] * np.array([-pivot[1], pivot[0]])
    v_contact = v_pivot + (twist[2] + cmd.beta_rate[0]) * 0.04 * np.array([-rolling[1], rolling[0]])
    assert abs(v_contact @ axle) < 1e-12
    assert_allclose(cmd.rim_speed[0], v_contact @ rolling, atol=1e-12)
    assert not cmd.beta_rate[1:].any()
    assert np.linalg.norm(contact - pivot) == pytest.approx(0.04)


# --- ICR locus classification (§3.6, corrected criterion) ------------------------------------------------------


def _fixed(x, y, heading):
    return Wheel.placed(WheelType.FIXED, x, y, heading, radius=0.02)


def test_icr_locus_classification():
    axle = [_fixed(0, 0.1, 0), _fixed(0, -0.1, 0)]
    assert icr_locus(presets.omni4()).kind == "anywhere"
    assert icr_locus(Chassis.from_wheels(axle + [_fixed(0, 0.3, np.pi)])).kind == "line"  # coinciding axles
    concurrent = Chassis.from_wheels(axle + [Wheel(WheelType.FIXED, 0.2, 0.0, np.pi / 4, 0.02)])
    locus = icr_locus(concurrent)  # thesis criterion: "line"
    assert locus.kind == "point"
    assert_allclose(locus.point, [0, -0.2], atol=1e-12)
    parallel = Chassis.from_wheels([Wheel(WheelType.FIXED, 0.1, np.pi / 2, 0.0, 0.02),
                                    Wheel(WheelType.FIXED, 0.2, 0.0, np.pi / 2, 0.02)])
    locus = icr_locus(parallel)
    assert locus.kind == "infinity"
    same_span(motion_subspaces(parallel).Z, [1, 0, 0])  # translation only, normal to the axles
    assert_allclose(np.abs(locus.normal), [1, 0], atol=1e-12)
    stuck = Chassis.from_wheels(axle + [_fixed(0.2, 0.0, np.pi / 2), _fixed(-0.2, 0.05, np.pi / 2)])
    assert icr_locus(stuck).kind == "immobile"
    assert motion_subspaces(stuck).Z.shape[1] == 0


@pytest.mark.parametrize("preset, delta_m, delta_s", [
    (presets.differential_drive, 2, 0), (presets.tricycle, 1, 1), (presets.ackermann, 1, 1),
    (presets.mecanum4, 3, 0), (presets.omni3, 3, 0), (presets.omni4, 3, 0), (presets.steered3, 1, 2),
    (presets.steered4, 1, 2),
])
def test_degree_of_mobility_and_steerability(preset, delta_m, delta_s):
    m = mobility(preset())
    assert (m.mobility, m.steerability, m.maneuverability) == (delta_m, delta_s, delta_m + delta_s)


def test_frozen_steering_lowers_steerability():
    chassis = degrade(STEERED3, Failure(2, steering=True))
    assert (mobility(chassis).mobility, mobility(chassis).steerability) == (1, 1)
    assert_allclose(chassis.beta, STEERED3.beta)  # frozen where it stood
    with pytest.raises(ValueError, match="not a steered wheel"):
        degrade(OMNI4, Failure(0, steering=True))


def test_ackermann_angles_meet_at_the_rear_axle():
    """cot δ_outer − cot δ_inner = b/a: both front wheels point at one ICR on the rear axle line."""
    a, b = 0.5, 0.4
    chassis = presets.ackermann(wheelbase=a, track=b)
    cmd = inverse_kinematics(chassis, [1.0, 0.0, 1.5])
    inner, outer = cmd.heading[0], cmd.heading[1]
    assert inner > outer > 0
    assert 1 / np.tan(outer) - 1 / np.tan(inner) == pytest.approx(b / a)
    assert_allclose(cmd.rim_speed[2:], [1 - 1.5 * b / 2, 1 + 1.5 * b / 2])


def test_world_frame_icr_of_the_linear_position_controller():
    """§3.5 [derived]: x, y, θ decaying alike from (1, 1, π/4): fixed centrode offset (4/π)(−1, 1)."""
    pose = np.array([1.0, 1.0, np.pi / 4])
    velocity = -0.7 * pose
    body = to_body(pose[2], velocity)
    assert_allclose(to_world(pose[2], body), velocity, atol=1e-15)
    h = icr(body)
    c = h[:2] / h[2]
    world = pose[:2] + to_world(pose[2], [*c, 0])[:2]
    assert_allclose(world, [-0.2732395, 2.2732395], atol=places(7))
    assert_allclose(twist_from_icr(h), body, atol=1e-15)


def test_forward_kinematics_reports_slip_when_wheels_fight():
    twist = np.array([0.4, -0.3, 0.9])
    cmd = inverse_kinematics(STEERED3, twist)
    clean = forward_kinematics(STEERED3, cmd.phi_dot, cmd.beta)
    assert_allclose(clean.twist, twist, atol=1e-12)
    assert_allclose(forward_kinematics(STEERED3.with_beta(cmd.beta), cmd.phi_dot).twist, twist, atol=1e-12)
    assert clean.slip < 1e-12 and clean.rank == 3
    fighting = forward_kinematics(STEERED3, cmd.phi_dot + [5.0, 0, 0], cmd.beta)
    assert fighting.slip > 0.01
    # least squares: the residual is orthogonal to the columns of the system
    assert np.abs(fighting.rolling).max() < 5.0 * 0.02


def test_forward_kinematics_omni4_least_squares():
    """ξ = (J₂⁻¹J₁)⁺φ̇ (§2.10) for the over-determined omni chassis."""
    phi_dot = np.array([1.0, 2.0, -3.0, 0.5])
    fk = forward_kinematics(OMNI4, phi_dot)
    assert_allclose(fk.twist, np.linalg.pinv(np.linalg.solve(radius_matrix(OMNI4), rolling_matrix(OMNI4))) @ phi_dot)
    assert fk.slip > 0


def test_chassis_validation():
    with pytest.raises(ValueError, match="degenerate"):
        Chassis.from_wheels([Wheel(WheelType.OMNI, 0.2, 0.0, 0.0, 0.02, gamma=np.pi / 2)])
    with pytest.raises(ValueError, match="castor needs offset"):
        Chassis.from_wheels([Wheel(WheelType.CASTOR, 0.2, 0.0, 0.0, 0.02)])
    with pytest.raises(ValueError, match="only omni wheels"):
        Chassis.from_wheels([Wheel(WheelType.FIXED, 0.2, 0.0, 0.0, 0.02, gamma=0.1)])
    chassis = presets.ctbot()
    assert not chassis.beta.flags.writeable
    assert chassis.names == ("left", "right")
