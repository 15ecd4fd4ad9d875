"""Run ctsim's benchmarks and print one line per figure: `name: value unit` (DESIGN.md §7).

    python bench/run.py            # full
    python bench/run.py --quick    # a short version
    python bench/run.py -k world   # only figures whose name contains 'world'
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench import kinematics  # noqa: E402


def figures(quick: bool):
    """(name, unit, thunk) for every benchmark; `quick` shortens the runs."""
    scale = 0.2 if quick else 1.0
    yield "kinematics_batch_10k", "robot-steps/s", lambda: kinematics.kinematics_batch(steps=int(3000 * scale))
    yield "kinematics_batch_10k_numpy", "robot-steps/s", lambda: kinematics.kinematics_batch_numpy(steps=int(1000 * scale))
    yield "kinematics_batch_10k_irsim_x", "robot-steps/s (C++ peer, one thread; nan: not installed)", lambda: kinematics.irsim_batch(steps=int(2000 * scale))
    yield "kinematics_batch_10k_over_irsim_x", "(fused kernel / irsim-x's pose-only step, interleaved; nan: not installed)", lambda: kinematics.irsim_ratio(steps=int(1000 * scale))
    yield "kinematics_poses_10k", "robot-steps/s (pose-only kernel)", lambda: kinematics.kinematics_batch(steps=int(3000 * scale), poses=True)
    yield "kinematics_poses_10k_over_irsim_x", "(pose-only kernel / irsim-x, the same work, interleaved; nan: not installed)", lambda: kinematics.irsim_ratio(steps=int(1000 * scale), poses=True)
    yield "kinematics_batch_10k_parallel", "robot-steps/s", lambda: kinematics.kinematics_batch(steps=int(3000 * scale), parallel=True)
    yield "kinematics_batch_parallel_ratio", "(parallel / serial, same run; bar >= 1.7 on two cores)", lambda: kinematics.parallel_ratio(steps=int(500 * scale))
    yield "kinematics_poses_parallel_ratio", "(parallel / serial pose-only kernel, same run)", lambda: kinematics.parallel_ratio(steps=int(500 * scale), poses=True)
    yield ("kinematics_batch_100k_parallel_ratio", "(parallel / serial, 100,000 robots: the threads' start-up spread over ten times the work)",
           lambda: kinematics.parallel_ratio(robots=100_000, steps=max(int(50 * scale), 10), pairs=10))
    yield "arc_circle_error_dt0.1", "m", lambda: kinematics.arc_circle_error(dt=0.1)
    try:
        from bench import world
    except ImportError:
        return
    from bench import bridge, experiments, first_run, lab, localiser, main_job, memory, sigma_points

    for module in (main_job, world, localiser, bridge, lab, experiments, memory, first_run, sigma_points):
        yield from module.figures(scale)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="shorter runs (less precise figures)")
    parser.add_argument("-k", dest="pattern", default="", help="only figures whose name contains this")
    args = parser.parse_args(argv)
    for name, unit, thunk in figures(args.quick):
        if args.pattern in name:
            value = thunk()
            text = f"{value:.3g}" if abs(value) < 1e-3 else f"{value:,.0f}" if value >= 100 else f"{value:.4g}"
            print(f"{name}: {text} {unit}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
