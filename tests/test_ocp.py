"""Omni-Curve-Parameters against the numbers of omni-curve-parameters.md §4.2 (tables A-H) and properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from printed import places

from sim.kinematics import chassis_presets as presets
from sim.kinematics import wrap_angle
from sim.kinematics.arc import apply_increment, se2_exp
from sim.kinematics.chassis import InfeasibleTwist, WheelType, forward_kinematics, icr
from sim.kinematics.ocp import (
    configuration_space,
    icr_to_ocp,
    kappa_g_for,
    kappa_n_from_rho,
    ocp_grid,
    ocp_icr,
    ocp_to_twist,
    rho_from_kappa_n,
    sgn,
    twist_to_ocp,
    v_max_for,
    wheel_setpoints,
)

DEG = np.pi / 180


# --- A. definition --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kn, v, omega, radius", [
    (0, 1, 0, np.inf), (0.5, 1, 1, 1.0), (1.0, 1, 2, 0.5), (1.5, 0.5, 2, 0.25), (2.0, 0, 2, 0),
    (-0.5, 1, -1, -1.0), (-1.0, 1, -2, -0.5), (-1.5, 0.5, -2, -0.25), (-2.0, 0, -2, 0),
])
def test_table_a_definition(kn, v, omega, radius):
    assert_allclose(ocp_to_twist(kn, 0.0, 1.0, 2.0), [v, 0, omega], atol=1e-15)
    with np.errstate(divide="ignore"):
        assert 1 / (2.0 * rho_from_kappa_n(kn)) == pytest.approx(radius)  # R = 1/(κ_g ρ)
    assert kappa_n_from_rho(rho_from_kappa_n(kn)) == pytest.approx(kn)


def test_switch_at_one_is_continuous_but_kinked():
    assert_allclose(ocp_to_twist(0.999999, 0.0, 1.0, 2.0), [1, 0, 1.999998], atol=1e-12)
    assert 1 / (2 * rho_from_kappa_n(0.999999)) == pytest.approx(0.500001)
    eps = 1e-7
    below, at, above = ocp_to_twist([1 - eps, 1.0, 1 + eps], 0.0, 1.0, 2.0)
    assert_allclose(below, at, atol=1e-6) and assert_allclose(above, at, atol=1e-6)  # 1e-7 either side moves ω by 2e-7 (slope v_s κ_g = 2)
    assert_allclose((at - below) / eps, [0, 0, 2], atol=1e-6)  # dω/dκ_n = v_s κ_g below
    assert_allclose((above - at) / eps, [-1, 0, 0], atol=1e-6)  # dv/dκ_n = −v_s above


def test_sharp_branch_v_equals_omega_r_and_sgn_has_no_zero():
    kn = np.linspace(-2, 2, 81)
    twist = ocp_to_twist(kn, 0.0, 0.7, 3.0)
    sharp = np.abs(kn) >= 1
    radius = (2 * sgn(kn) - kn) / 3.0
    assert_allclose(twist[sharp, 0], twist[sharp, 2] * radius[sharp], atol=1e-14)
    assert sgn(0.0) == 1 and sgn(-0.0) == 1 and sgn(-1e-300) == -1
    with pytest.raises(ValueError, match=r"\[−2, 2\]"):
        ocp_to_twist(2.5, 0.0, 1.0, 1.0)


def test_reversal_retraces_the_same_icr():
    forwards, backwards = ocp_icr(0.7, 0.3, 2.0), icr(ocp_to_twist(0.7, 0.3, -1.0, 2.0))
    assert_allclose(forwards[:2] / forwards[2], backwards[:2] / backwards[2])
    assert_allclose(ocp_icr(2.0, 1.0, 2.0)[:2], 0, atol=1e-15)  # spot turn about K
    assert ocp_icr(0.0, 0.3, 2.0)[2] == 0  # straight line: ICR at infinity


# --- B. twist → OCP ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("v, omega, kn, v_s", [
    (0, 1, 2, 0.5), (0, -1, -2, 0.5), (-1, 1, -0.5, -1), (1, 2, 1, 1), (1, 4, 1.5, 2),
])
def test_table_b_twist_to_ocp(v, omega, kn, v_s):
    result = twist_to_ocp([v, 0.0, omega], 2.0, convention="line")
    assert_allclose(result, (kn, 0.0, v_s), atol=1e-15)


def test_standstill_and_spot_turn_keep_the_configuration():
    assert_allclose(twist_to_ocp([0, 0, 0], 2.0, beta_prev=0.4, kappa_prev=1.3), (1.3, 0.4, 0.0))
    assert_allclose(twist_to_ocp([0, 0, -3], 2.0, beta_prev=0.4), (-2, 0.4, 1.5))


def test_line_convention_refuses_lateral_motion():
    with pytest.raises(InfeasibleTwist, match="line-mobile") as info:
        twist_to_ocp([[1.0, 0.2, 0.5], [1.0, 0.0, 0.5]], 2.0, convention="line")
    assert info.value.mask.tolist() == [True, False]
    assert_allclose(info.value.nearest[0], [1.0, 0.0, 0.5])


# --- C. differential drive -------------------------------------------------------------------------------------

DIFF_TABLE = [(0, 1, 1), (0.25, 0.75, 1.25), (0.5, 0.5, 1.5), (0.75, 0.25, 1.75), (1, 0, 2), (1.25, -0.25, 1.75),
              (1.5, -0.5, 1.5), (1.75, -0.75, 1.25), (2, -1, 1), (-0.5, 1.5, 0.5), (-1, 2, 0), (-1.5, 1.5, -0.5),
              (-2, 1, -1)]


@pytest.mark.parametrize("kn, u1, u2", DIFF_TABLE)
def test_table_c_differential_drive(kn, u1, u2):
    chassis = presets.differential_drive(track=0.23)
    assert kappa_g_for(chassis) == pytest.approx(2 / 0.23)
    cmd = wheel_setpoints(chassis, kn, 0.0, 1.0, 2 / 0.23)
    assert_allclose(cmd.rim_speed, [u1, u2], atol=1e-12)
    # the generic path: (|u_i|, α_i) with α_i = 180° for a wheel rolling backwards
    heading = np.where(cmd.rim_speed < 0, np.pi, 0.0)
    assert_allclose(np.abs(wrap_angle(cmd.heading + (cmd.rim_speed < 0) * np.pi - heading)), 0, atol=1e-12)


def test_differential_drive_sharp_branch_typo_and_odometry():
    chassis = presets.differential_drive(track=0.23)
    kappa_g = kappa_g_for(chassis)
    # the paper's literal form would give (−0.75, 1.25) at v_s = 0.5
    assert_allclose(wheel_setpoints(chassis, 1.5, 0.0, 0.5, kappa_g).rim_speed, [-0.25, 0.75], atol=1e-12)
    assert kappa_g == pytest.approx(8.695652, abs=places(6))
    twist = ocp_to_twist(0.5, 0.0, 1.0, kappa_g)
    assert twist[2] == pytest.approx(4.347826, abs=places(6))
    assert np.diff(wheel_setpoints(chassis, 0.5, 0.0, 1.0, kappa_g).rim_speed)[0] == pytest.approx(1.0)


@pytest.mark.parametrize("u1, u2, kn, v_s", [
    (0.5, 1.5, 0.5, 1), (-1, 1, 2, 1), (1, -1, -2, 1), (0, 2, 1, 1), (2, 0, -1, 1), (-0.25, 1.75, 1.25, 1),
    (-1, -1, 0, -1), (-1.5, -0.5, -0.5, -1), (0.3, 0.3, 0, 0.3), (0.6, -0.2, -1.5, 0.4), (0, 0, 0, 0),
])
def test_table_c_wheel_speeds_to_ocp(u1, u2, kn, v_s):
    chassis = presets.differential_drive(track=0.23, wheel_radius=0.03)
    twist = forward_kinematics(chassis, np.array([u1, u2]) / 0.03).twist
    result = twist_to_ocp(twist, 2 / 0.23, convention="line")
    assert_allclose(result, (kn, 0.0, v_s), atol=1e-12)


def test_differential_drive_v_max_curve():
    chassis = presets.differential_drive(track=0.23, max_speed=1.0)
    kn = np.array([0, 0.5, 1, 1.5, 2, -0.5, -1.5])
    space = configuration_space(chassis, kn, 0.0)
    assert_allclose(space.v_max, [1, 2 / 3, 0.5, 2 / 3, 1, 2 / 3, 2 / 3], atol=1e-12)
    assert_allclose(space.v_max, np.where(np.abs(kn) < 1, 1 / (1 + np.abs(kn)), 1 / (3 - np.abs(kn))))
    # a line-mobile chassis cannot drive sideways: those configurations are blocked
    assert configuration_space(chassis, 0.3, 0.5).blocked
    assert v_max_for(chassis) == 1.0


# --- D. Ackermann single track, E. tricycle ---------------------------------------------------------------------

ACKERMANN = [(0, 1, 1, 0), (0.25, 1.030776, 1, 14.0362), (0.5, 1.118034, 1, 26.5651), (1, 1.414214, 1, 45),
             (1.5, 1.118034, 0.5, 63.4349), (1.75, 1.030776, 0.25, 75.9638), (2, 1, 0, 90)]


@pytest.mark.parametrize("wheelbase", [1.0, 0.43])
@pytest.mark.parametrize("kn, u1, u2, alpha1", ACKERMANN)
def test_table_d_ackermann_single_track(wheelbase, kn, u1, u2, alpha1):
    chassis = presets.tricycle(wheelbase=wheelbase, track=0.0)
    kappa_g = kappa_g_for(chassis)
    assert kappa_g == pytest.approx(1 / wheelbase)
    for sign in (1, -1):  # odd symmetry: α changes sign, u does not
        cmd = wheel_setpoints(chassis, sign * kn, 0.0, 1.0, kappa_g)
        assert_allclose(cmd.rim_speed, [u1, u2, u2], atol=places(6))
        assert np.degrees(cmd.heading[0]) == pytest.approx(sign * alpha1, abs=places(4))
        assert_allclose(cmd.heading[1:], 0, atol=1e-12)


def test_ackermann_linear_approximation_error_and_steering_limit():
    chassis = presets.tricycle(wheelbase=1.0, track=0.0)
    kn = np.linspace(0, 2, 200001)
    alpha1 = wheel_setpoints(chassis, kn, 0.0, 1.0, 1.0).heading[:, 0]
    error = np.degrees(alpha1 - np.pi / 4 * kn)
    assert error.max() == pytest.approx(4.074569, abs=1e-5)  # the grid's step: the maximum is found to 1e-5 in κ_n, far less in error
    assert kn[np.argmax(error)] == pytest.approx(0.522723, abs=1e-5)  # the grid's step (200,001 points over 0..2)
    assert kn[np.argmin(error)] == pytest.approx(2 - 0.522723, abs=1e-5)  # the grid's step
    for limit, kn_max in [(20, 0.363970), (30, 0.577350), (45, 1), (60, 1.422650), (75, 1.732051), (90, 2)]:
        kn_limit = kappa_n_from_rho(np.tan(np.radians(limit)))  # tan α₁ = a κ = ρ
        assert kn_limit == pytest.approx(kn_max, abs=1e-6)
        assert wheel_setpoints(chassis, kn_limit, 0.0, 1.0, 1.0).heading[0] == pytest.approx(np.radians(limit))


@pytest.mark.parametrize("kn, front, left, right", [
    (0.5, (1.118034, 26.565), (0.875, 0), (1.125, 0)),
    (1, (1.414214, 45), (0.75, 0), (1.25, 0)),
    (2, (1, 90), (-0.25, 0), (0.25, 0)),
    (-1.5, (1.118034, -63.435), (0.75, 0), (0.25, 0)),
])
def test_table_e_tricycle(kn, front, left, right):
    chassis = presets.tricycle(wheelbase=1.0, track=0.5)
    assert kappa_g_for(chassis) == 1.0
    cmd = wheel_setpoints(chassis, kn, 0.0, 1.0, 1.0)
    assert_allclose(cmd.rim_speed, [front[0], left[0], right[0]], atol=places(6))
    assert_allclose(np.degrees(cmd.heading), [front[1], left[1], right[1]], atol=places(3))


# --- F. four steered wheels, the paper's example vehicle ---------------------------------------------------------

STEERED4 = presets.steered4(max_speed=1.0)
KAPPA_G4 = 4.101324


@pytest.mark.parametrize("kn, beta, u, alpha, blocked, v_max", [
    (0, 0, (1, 1, 1, 1), (0, 0, 0, 0), False, 1),
    (0.5, 0, (0.882240, 1.312117, 0.882240, 1.312117), (29.983, 19.634, -29.983, -19.634), False, 0.762127),
    (1, 0, (1.027957, 1.715606, 1.027957, 1.715606), (59.071, 30.929, -59.071, -30.929), False, 0.582884),
    (1.5, 0, (0.882240, 1.312117, 0.882240, 1.312117), (88.159, 42.224, -88.159, -42.224), False, 0.762127),
    (2, 0, (1, 1, 1, 1), (118.142, 61.858, -118.142, -61.858), False, 1),
    (2, 77, (1, 1, 1, 1), (118.142, 61.858, -118.142, -61.858), False, 1),
    (-2, -130, (1, 1, 1, 1), (-61.858, -118.142, 61.858, 118.142), False, 1),
    (1.9, 0, (0.9569, 1.0509, 0.9569, 1.0509), (112.854, 57.045, -112.854, -57.045), False, 0.951591),
    (-1, 0, (1.715606, 1.027957, 1.715606, 1.027957), (-30.929, -59.071, 30.929, 59.071), False, 0.582884),
    (1, 90, (1.939992, 1.939992, 0.486241, 0.486241), (104.071, 75.929, 165.929, 14.071), True, 0),
    (1, -90, (0.486241, 0.486241, 1.939992, 1.939992), (-165.929, -14.071, -104.071, -75.929), True, 0),
    (0.5, 45, (1.240970, 1.485606, 0.541272, 0.979792), (67.681, 50.601, 29.461, 15.766), False, 0.673126),
    (1.5, 120, (1.499825, 1.333350, 0.849811, 0.500526), (118.761, 80.431, -148.124, -63.715), False, 0.666745),
    (-1.5, -60, (1.499825, 1.333350, 0.849811, 0.500526), (-61.239, -99.569, 31.876, 116.285), False, 0.666745),
])
def test_table_f_four_steered_wheels(kn, beta, u, alpha, blocked, v_max):
    assert kappa_g_for(STEERED4) == pytest.approx(KAPPA_G4, abs=places(6))
    space = configuration_space(STEERED4, kn, beta * DEG)
    assert_allclose(space.rim_speed, u, atol=places(4))
    assert_allclose(np.degrees(space.heading), alpha, atol=places(3))
    assert bool(space.blocked) == blocked
    assert float(space.v_max) == pytest.approx(v_max, abs=places(6))


def test_four_steered_blocked_region_facts():
    edge = configuration_space(STEERED4, 0.0, np.radians([155.0, 155.5, -156.0, -155.0]))
    assert edge.blocked.tolist() == [False, True, True, False]
    kn, beta = ocp_grid(161, 361)
    space = configuration_space(STEERED4, kn, beta)
    assert space.blocked.mean() == pytest.approx(0.2394, abs=places(4) / 2)  # the share of a 161 x 361 grid, printed with four decimals
    assert not space.blocked[np.abs(beta) < np.radians(61.858)].any()  # free band around β = 0
    assert not space.blocked[np.abs(kn) >= 1.45].any()
    assert_allclose(space.v_max[(kn == 0) & ~space.blocked], 1.0)  # every wheel equally fast
    assert_allclose(space.v_max[np.abs(kn) == 2], 1.0)
    assert_allclose(space.rim_speed[kn == 0][..., 3], 1.0)
    assert (space.blocked == space.blocked[::-1]).all() and (space.blocked == space.blocked[:, ::-1]).all()
    ones = space.v_max[(np.abs(kn) == 1) & ~space.blocked]
    assert ones.min() > 0.5 - 1e-9 and ones.max() == pytest.approx(0.582884, abs=places(6))


@pytest.mark.parametrize("kn, feasible", [(0.25, 140.54), (0.5, 125.04), (0.9, 91.01), (1.25, 78.10), (1.4, 113.67)])
def test_four_steered_feasible_beta_intervals(kn, feasible):
    beta = np.radians(np.array([feasible - 0.02, feasible + 0.02]))
    assert configuration_space(STEERED4, kn, beta).blocked.tolist() == [False, True]


def test_singular_points_and_the_steering_jump_at_them():
    singular = np.radians(90) - np.arctan(0.23 / 0.43)
    assert np.degrees(singular) == pytest.approx(61.858, abs=places(3))
    points = {0: (1, -singular), 1: (-1, singular), 2: (1, singular), 3: (-1, -singular)}
    for wheel, (kn, beta) in points.items():
        space = configuration_space(STEERED4, kn, beta)
        assert space.blocked and space.v_max == 0
        assert abs(space.rim_speed[wheel]) < 1e-12
    peak = configuration_space(STEERED4, 1, -singular).rim_speed[3]
    assert peak == pytest.approx(2.0)  # u₄ is largest with the ICR on the diagonally opposite W₁
    # α₂ jumps by 180° across its singular point at (κ_n, β) = (−1, 61.858°)
    approaches = [((1e-4, 0), 61.858), ((-1e-4, 0), -118.142), ((0, 1e-3), 151.887), ((0, -1e-3), -28.170)]
    for (dk, db), expected in approaches:
        heading = configuration_space(STEERED4, -1 + dk, singular + db).heading[1]
        assert np.degrees(heading) == pytest.approx(expected, abs=0.05)  # 1e-4 (resp. 1e-3) from the singular point the heading is within 0.05° of its one-sided limit
    # a margin around the singular points only ever grows the blocked set
    kn, beta = ocp_grid(41, 73)
    plain = configuration_space(STEERED4, kn, beta).blocked
    wide = configuration_space(STEERED4, kn, beta, margin=0.05).blocked
    assert (wide >= plain).all() and wide.sum() > plain.sum()


# --- G. Mecanum ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kn, beta, rim, v_max", [
    (0, 0, (1, 1, 1, 1), 1), (0, 45, (0, 1.414214, 1.414214, 0), 0.707107), (0, 90, (-1, 1, 1, -1), 1),
    (0.5, 0, (0.323282, 1.676718, 0.323282, 1.676718), 0.596403),
    (1, 0, (-0.353437, 2.353437, -0.353437, 2.353437), 0.424910),
    (2, 0, (-1.353437, 1.353437, -1.353437, 1.353437), 0.738860),
    (2, 100, (-1.353437, 1.353437, -1.353437, 1.353437), 0.738860),
    (-1.5, 30, (1.53645, -0.670424, 2.03645, -1.170424), 0.491051),
])
def test_table_g_mecanum(kn, beta, rim, v_max):
    chassis = presets.mecanum4(max_speed=1.0)
    assert kappa_g_for(chassis) == pytest.approx(KAPPA_G4, abs=places(6))
    space = configuration_space(chassis, kn, beta * DEG)
    assert_allclose(space.rim_speed, rim, atol=places(6))
    assert float(space.v_max) == pytest.approx(v_max, abs=places(6))
    cmd = wheel_setpoints(chassis, kn, beta * DEG, 0.5, KAPPA_G4)
    assert_allclose(cmd.phi_dot, 0.5 * np.array(rim) / 0.05, atol=places(6) * 0.5 / 0.05)  # rim speeds printed to six places, times v_s / r


def test_mecanum_matrix_rows():
    """r φ̇ = M (v_x, v_y, ω) with the standard M of OCP §2.3."""
    lx, ly = 0.215, 0.115
    m = np.array([[1, -1, -(lx + ly)], [1, 1, lx + ly], [1, 1, -(lx + ly)], [1, -1, lx + ly]])
    twist = np.array([0.3, -0.7, 1.1])
    rim = wheel_setpoints(presets.mecanum4(), *twist_to_ocp(twist, KAPPA_G4), KAPPA_G4).rim_speed
    assert_allclose(rim, m @ twist, atol=1e-12)


# --- H. exact arc integration of constant OCP -----------------------------------------------------------------

@pytest.mark.parametrize("start, ocp, end", [
    ((0, 0, 0), (0.5, 0, 1, 2, np.pi / 2), (1, 1, np.pi / 2)),
    ((0, 0, 0), (2, 0.3, 1, 2, 1), (0, 0, 2)),
    ((0, 0, 0), (1.5, np.pi / 2, 1, 2, np.pi / 2), (-0.5, 0, np.pi)),
    ((0, 0, 0), (0, np.pi / 4, 1, 2, 2), (1.414214, 1.414214, 0)),
    ((1, 2, 0.5), (-0.7, -0.4, 0.8, 4.1, 0.9), (1.356306, 1.519035, -1.5664)),
    ((0, 0, 0), (-1.2, 0, -1, 1 / 0.43, 0.7), (-0.343439, -0.363635, 1.627907)),
])
def test_table_h_exact_pose_integration(start, ocp, end):
    kn, beta, v_s, kappa_g, dt = ocp
    twist = ocp_to_twist(kn, beta, v_s, kappa_g)
    assert_allclose(apply_increment(np.array(start, float), se2_exp(twist * dt)), end, atol=places(6))


# --- κ_g, set-points at standstill ------------------------------------------------------------------------------

def test_kappa_g_rules():
    assert kappa_g_for(presets.tricycle(wheelbase=0.3, track=1.0)) == pytest.approx(2.0)  # 1/max(a, b/2)
    assert kappa_g_for(presets.omni4()) == pytest.approx(5.0)
    # unequal limits: the wheel with the largest |w|/u_lim decides
    slow = presets.steered4(max_speed=1.0)
    assert kappa_g_for(slow) == pytest.approx(KAPPA_G4, abs=places(6))


def test_pre_steering_at_standstill():
    cmd = wheel_setpoints(STEERED4, 1.5, 0.0, 0.0, KAPPA_G4)
    assert_allclose(np.degrees(cmd.heading), [88.159, 42.224, -88.159, -42.224], atol=places(3))
    assert not cmd.phi_dot.any()


# --- properties ------------------------------------------------------------------------------------------------

kappa_n = st.floats(-2, 2, allow_nan=False)
beta = st.floats(-np.pi, np.pi, allow_nan=False)
speed = st.floats(-3, 3, allow_nan=False).filter(lambda v: abs(v) > 1e-3)
limit = st.floats(0.5, 10)


def _near(a, b):
    return abs(wrap_angle(a - b)) < 1e-9


@settings(max_examples=300)
@given(kappa_n.filter(lambda k: 1e-6 < abs(k) < 2 - 1e-6), beta, speed, limit)
def test_round_trip_ocp_twist_ocp(kn, b, v_s, kappa_g):
    """Away from the singular points (κ_n = 0: no mirror; |κ_n| = 2: β free), OCP → twist → OCP holds;
    "continuity" returns the original, "forward" its mirror image when v_s < 0, consistently."""
    twist = ocp_to_twist(kn, b, v_s, kappa_g)
    back = twist_to_ocp(twist, kappa_g, convention="continuity", beta_prev=b)
    assert back[0] == pytest.approx(kn, abs=1e-9) and _near(back[1], b) and back[2] == pytest.approx(v_s)
    kf, bf, vf = twist_to_ocp(twist, kappa_g)
    assert vf > 0
    mirror = v_s < 0
    assert kf == pytest.approx(-kn if mirror else kn, abs=1e-9)
    assert _near(bf, b + np.pi if mirror else b) and vf == pytest.approx(abs(v_s))
    assert_allclose(ocp_to_twist(kf, bf, vf, kappa_g), twist, atol=1e-9)


@settings(max_examples=200)
@given(kappa_n, beta, speed, limit)
def test_mirror_identity_and_icr_round_trip(kn, b, v_s, kappa_g):
    twist = ocp_to_twist(kn, b, v_s, kappa_g)
    if kn != 0:
        assert_allclose(ocp_to_twist(-kn, b + np.pi, -v_s, kappa_g), twist, atol=1e-9)
    h = icr(twist)  # ICR scaled by the motion carries the whole twist
    assert_allclose(ocp_to_twist(*icr_to_ocp(h, kappa_g, beta_prev=b), kappa_g), twist, atol=1e-9)
    unit = ocp_icr(kn, b, kappa_g)
    assert_allclose(np.cross(unit, h), 0, atol=1e-9)  # same projective point for any v_s


@settings(max_examples=100)
@given(kappa_n, beta)
def test_setpoints_scale_with_speed_and_keep_the_path(kn, b):
    one = wheel_setpoints(STEERED4, kn, b, 1.0, KAPPA_G4)
    half = wheel_setpoints(STEERED4, kn, b, -0.5, KAPPA_G4)
    assert_allclose(half.rim_speed, -0.5 * one.rim_speed, atol=1e-12)
    assert_allclose(half.heading, one.heading)
    assert (one.rim_speed >= 0).all()  # sign follows v_s, direction is carried by α_i


@pytest.mark.parametrize("preset", [presets.ctbot, presets.differential_drive, presets.tricycle, presets.ackermann,
                                    presets.mecanum4, presets.omni3, presets.omni4, presets.steered3,
                                    presets.steered4])
def test_setpoints_for_every_preset_drive_the_commanded_twist(preset):
    chassis = preset()
    kappa_g = kappa_g_for(chassis)
    line = (chassis.kind == WheelType.FIXED).any()  # fixed wheels: line-mobile, β ≡ 0
    kn = np.array([0.0, 0.4, 1.0, 1.6, -0.7, -1.3])
    b = np.zeros_like(kn) if line else np.array([0.0, 0.5, -1.0, 2.5, 0.3, -0.2])
    cmd = wheel_setpoints(chassis, kn, b, 0.8, kappa_g)
    fk = forward_kinematics(chassis, cmd.phi_dot, cmd.beta)
    assert_allclose(fk.twist, ocp_to_twist(kn, b, 0.8, kappa_g), atol=1e-9)
    assert (fk.slip < 1e-9).all()
    if line:
        with pytest.raises(InfeasibleTwist):
            wheel_setpoints(chassis, 0.4, 0.5, 0.8, kappa_g)
