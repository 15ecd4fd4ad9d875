"""A user's own estimator from a file, beside the shipped ones in every output of `ctsim run`
and `simulate`; one that raises, returns NaN or the wrong shape ends the run as a controller's
error does (one line, exit 1, everything up to the failure written)."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from sim.cli.entry import main
from sim.experiments import simulate

EULER = '''
import math
import numpy as np

class Euler:
    """Encoder odometry integrated with Euler's method, with a covariance that is a guess."""
    name = "euler"

    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
        self.tick = math.pi * robot.wheel_diameter / robot.encoders.ticks_per_rev
        self.track = robot.track_width
        self.covariance = np.eye(3) * 1e-6

    def update(self, readings):
        left, right = readings.encoder_ticks * self.tick
        s, alpha = 0.5 * (left + right), (right - left) / self.track
        self.pose = self.pose + [s * math.cos(self.pose[2]), s * math.sin(self.pose[2]), alpha]
        self.covariance = self.covariance + np.eye(3) * 1e-8
'''


def _file(tmp_path, text: str, name: str = "mine.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_a_user_estimator_is_in_the_summary_the_files_and_the_recording(tmp_path, capsys):
    from rerun.chunk import RrdReader

    path = _file(tmp_path, EULER)
    out = tmp_path / "run"
    assert main(["run", "maze", "--noise", "realistic", "--duration", "1", "--estimator", f"{path}:Euler", "--out", str(out), "--no-report"]) == 0
    table = capsys.readouterr().out
    assert "euler" in table
    summary = json.loads((out / "summary.json").read_text())
    (robot,) = summary["robots"]
    assert list(robot["estimates"]) == ["encoders", "firmware", "mouse", "fused", "euler"]
    assert robot["estimates"]["euler"]["nees_mean"] > 0 and robot["tum"]["euler"] == "euler.tum"
    lines = [line.split() for line in (out / "euler.tum").read_text().splitlines() if not line.startswith("#")]
    assert len(lines) == 101 and all(len(line) == 8 for line in lines)
    entities = {str(chunk.entity_path) for chunk in RrdReader(out / "run.rrd").stream().to_chunks()}
    assert {"/world/ctbot/trail/euler", "/world/ctbot/estimate/euler", "/world/ctbot/ellipse/euler"} <= entities
    import pyarrow.parquet as pq

    columns = pq.read_schema(out / "run.parquet").names
    assert "ctbot.euler.x" in columns and "ctbot.euler.cov_tt" in columns


def test_simulate_takes_estimators_too(tmp_path):
    path = _file(tmp_path, EULER)
    result = simulate("maze", duration=0.5, estimators=[f"{path}:Euler"])
    (robot,) = result.robots
    assert list(robot.estimates) == ["encoders", "firmware", "mouse", "fused", "euler"]
    assert robot.covariances["euler"].shape == (len(result.time), 6)
    # without a mistake of its own, Euler's method is the exact arc's estimate but for its chords
    assert np.abs(robot.estimates["euler"] - robot.estimates["encoders"]).max() < 0.01


@pytest.mark.parametrize(
    ("update", "said"),
    [
        ("raise RuntimeError('lost')", "raised RuntimeError: lost"),
        ("self.pose = np.array([np.nan, 0.0, 0.0])", "its pose is not finite (nan)"),
        ("self.pose = np.zeros(2)", "its pose has shape (2,); expected (3,)"),
        ("self.covariance = -np.eye(3)", "its covariance is not positive semi-definite (an eigenvalue of -1)"),
        ("self.covariance = np.array([[1.0, 0.1, 0], [0, 1, 0], [0, 0, 1]])", "its covariance is not symmetric ([0, 1] = 0.1, [1, 0] = 0)"),
    ],
)
def test_a_failing_user_estimator_ends_the_run_as_a_controller_error(tmp_path, capsys, update, said):
    path = _file(tmp_path, f"""
        import numpy as np

        class Broken:
            def reset(self, robot, pose):
                self.pose = np.array(pose, dtype=float)
                self.covariance = np.eye(3)

            def update(self, readings):
                if readings.time > 0.2:
                    {update}
    """)
    out = tmp_path / "run"
    assert main(["run", "maze", "--duration", "1", "--estimator", str(path), "--out", str(out), "--no-report"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if "Broken" in line]
    assert len(err) == 1 and said in err[0] and "step 21 (t = 0.21 s)" in err[0], err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "error" and said in summary["error"]
    assert (out / "run.rrd").is_file() and (out / "Broken.tum").is_file()


def test_a_user_estimator_may_not_take_a_shipped_name(tmp_path, capsys):
    path = _file(tmp_path, EULER.replace('name = "euler"', 'name = "fused"'))
    assert main(["run", "maze", "--duration", "0.1", "--estimator", str(path), "--out", str(tmp_path / "run")]) == 2
    assert "'fused' is taken" in capsys.readouterr().err
