"""The analysis layer: odometry against ground truth.

Trajectory error metrics (`metrics`), UMBmark calibration of systematic errors (`umbmark`) and
trajectory files for other tools (`export`: TUM for evo, CSV). It may import the kinematics core,
the robots, the world and the run loop; never the views or the command line.
"""

from sim.analysis.export import export_run, read_csv, read_tum, write_csv, write_tum
from sim.analysis.metrics import (
    Metrics,
    compare,
    compare_run,
    path_lengths,
    relative_pose_errors,
)

__all__ = [
    "Metrics", "compare", "compare_run", "export_run", "path_lengths", "read_csv", "read_tum",
    "relative_pose_errors", "write_csv", "write_tum",
]
