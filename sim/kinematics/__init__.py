"""The kinematics core: pure, vectorised maths of wheeled robots (numpy in, numpy out).

No pymunk, no I/O, no state: the world uses it for ground truth, the robot's own code for
odometry and control. Leading axes are batch axes; a single robot is a batch of one.
It imports numpy (and numba for the compiled batch kernels) and nothing else of the project.
"""

from sim.kinematics.arc import (
    Pose,
    advance,
    advance_floats,
    apply_increment,
    arc_increment,
    arc_to_wheel_arcs,
    compose,
    firmware_increment,
    half_angle_terms,
    integrate_arcs,
    relative_increment,
    relative_pose,
    se2_exp,
    se2_log,
    wheel_arcs_to_arc,
    wheel_increment,
    wrap_angle,
)
from sim.kinematics.diffdrive import (
    curvature,
    icc,
    turn_radius,
    twist_from_wheel_speeds,
    wheel_speeds_from_twist,
)
from sim.kinematics.encoders import (
    arcs_from_ticks,
    ticks_from_arc_series,
    ticks_from_arcs,
    ticks_per_metre,
)
from sim.kinematics.mouse import (
    MouseEstimator,
    UnobservableRotation,
    counts_per_metre,
    mouse_count_series,
    mouse_counts,
    mouse_displacement,
    mouse_displacement_from_increment,
)
from sim.kinematics.quantize import quantize, quantize_series

__all__ = [
    "Pose",
    "advance",
    "advance_floats",
    "MouseEstimator",
    "UnobservableRotation",
    "apply_increment",
    "arc_increment",
    "arc_to_wheel_arcs",
    "arcs_from_ticks",
    "compose",
    "counts_per_metre",
    "curvature",
    "firmware_increment",
    "half_angle_terms",
    "icc",
    "integrate_arcs",
    "mouse_count_series",
    "mouse_counts",
    "mouse_displacement",
    "mouse_displacement_from_increment",
    "quantize",
    "quantize_series",
    "relative_increment",
    "relative_pose",
    "se2_exp",
    "se2_log",
    "ticks_from_arc_series",
    "ticks_from_arcs",
    "ticks_per_metre",
    "turn_radius",
    "twist_from_wheel_speeds",
    "wheel_arcs_to_arc",
    "wheel_increment",
    "wheel_speeds_from_twist",
    "wrap_angle",
]
