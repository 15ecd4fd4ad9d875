"""`ctsim umbmark`: Borenstein and Feng's UMBmark of a robot, its corrections and the improvement,
with confidence intervals, a recommendation of how many runs its noise needs, and a figure."""

from __future__ import annotations

import argparse
import json
import textwrap
import time
from pathlib import Path
from typing import Any

from sim.cli.options import UsageError, add_robot_description, folder_name, load_robot_spec, positive, robot_options

PAPER_RUNS = 5
"""Runs each way in Borenstein and Feng's procedure."""
ROUNDS = 2
"""Rounds of measuring and correcting (`sim.analysis.umbmark.calibrate`: the second one removes
what the first-order formulas left)."""
TOLERANCE = 0.002
"""Half width (relative) of the 95 % intervals of E_d and E_b the recommended runs aim at."""


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `umbmark` command's options."""
    umbmark = commands.add_parser(
        "umbmark",
        help="calibrate a robot's wheel diameters and track by UMBmark squares",
        description="Borenstein and Feng's UMBmark: first the common scale of both wheels (E_s) from straight runs of known length, "
        "which squares cannot see; then drive squares clockwise and counter-clockwise by the robot's own encoder odometry, "
        "compute the wheel diameter ratio (E_d) and track (E_b) corrections from where they really end, correct, measure again "
        "(--rounds), and drive fresh squares with the calibrated geometry. Every run has noise of its own (no two share a seed). "
        "Prints E_max before and after and the corrections with 95 % confidence intervals (bootstrap over the squares), and how many "
        "runs each way this robot's noise needs; writes umbmark.png and umbmark.json.",
    )
    add_robot_description(umbmark)
    umbmark.add_argument("--runs", type=positive(int, 10_000), default=PAPER_RUNS, metavar="N",
                         help=f"squares each way per round and after (default: {PAPER_RUNS}, the paper's; random noise needs more: see the recommendation printed)")
    umbmark.add_argument("--rounds", type=positive(int, 10), default=ROUNDS, metavar="N", help=f"rounds of measuring and correcting (default: {ROUNDS})")
    umbmark.add_argument("--scale", action=argparse.BooleanOptionalAction, default=True,
                         help="first calibrate the wheels' common scale on --runs straight runs of --side metres (default: on; --no-scale: "
                         "the squares alone, which take a mean diameter error for a track error)")
    umbmark.add_argument("--side", type=positive(float, 20.0, "m"), default=1.0, metavar="METRES", help="the square's side (default: 1, as c't-Bot's floor allows; the paper's is 4)")
    umbmark.add_argument("--tolerance", type=positive(float, 1.0), default=TOLERANCE, metavar="FRACTION",
                         help=f"half width of the 95 %% intervals of E_d and E_b the recommended number of runs aims at (default: {TOLERANCE:g}, i.e. 0.2 %%)")
    umbmark.add_argument("--out", type=folder_name, metavar="DIR", help="folder for umbmark.png and umbmark.json (default: runs/umbmark-<time>)")
    umbmark.set_defaults(handler=cmd_umbmark)


def cmd_umbmark(args: argparse.Namespace) -> int:
    from sim.analysis.umbmark import calibrate, calibrated_belief, confidence, recommended_runs, scale_error, umbmark
    from sim.out_files import replacing
    from sim.views.umbmark_figure import write_umbmark_figure

    robot = load_robot_spec(args)
    if robot.chassis is not None:
        raise UsageError(f"robot {robot.name!r} is no differential drive: UMBmark calibrates two wheels and a track")
    out = Path(args.out if args.out is not None else Path("runs") / f"umbmark-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"{out}: cannot make the folder: {err.strerror or err}") from None
    scale = scale_error(robot, args.runs, args.side, seed=args.seed, dt=args.dt) if args.scale else None
    start, seed = (scale.corrected, scale.seeds[-1] + 1) if scale is not None else (None, args.seed)
    rounds = calibrate(robot, rounds=args.rounds, runs=args.runs, side=args.side, geometry=start, seed=seed, dt=args.dt)
    after = umbmark(robot, args.side, args.runs, rounds[-1].corrected, seed=rounds[-1].seeds[-1] + 1, dt=args.dt)
    intervals = [confidence(r, args.seed) for r in rounds]
    after_interval = confidence(after, args.seed)
    spread = recommended_runs(rounds[0], args.tolerance) if args.runs >= 2 else None
    print(f"UMBmark of {robot.name} (noise {args.noise}), {args.side:g} m squares, {args.runs} each way per round, seeds {args.seed}-{after.seeds[-1]}")
    if scale is not None:
        print(f"scale: E_s {_ratio(scale.e_s, scale.interval)} from {args.runs} straight runs of {args.side:g} m (true distance / counted)")
    print(f"{'round':<7}{'E_max mm (95 % CI)':<26}{'E_d (95 % CI)':<30}{'E_b (95 % CI)':<30}")
    for k, (r, ci) in enumerate(zip(rounds, intervals), 1):
        print(f"{k:<7}{_mm(r.max_error, ci['max_error']):<26}{_ratio(r.e_d, ci['e_d']):<30}{_ratio(r.e_b, ci['e_b']):<30}")
    print(f"{'after':<7}{_mm(after.max_error, after_interval['max_error']):<26}")
    final, ci = rounds[-1], intervals[-1]
    (left, right), track = final.corrected.wheel_diameters, final.corrected.track_width
    nominal = robot.track_width
    print(f"calibrated: wheels {left * 1000:.3f} / {right * 1000:.3f} mm (mean {100 * ((left + right) / 2 / robot.wheel_diameter - 1):+.2f} %, right/left {100 * (right / left - 1):+.2f} %), "
          f"track {track * 1000:.2f} mm ({100 * (track / nominal - 1):+.2f} %, 95 % CI {100 * (final.believed.track_width * ci['e_b'][0] / nominal - 1):+.2f} "
          f"to {100 * (final.believed.track_width * ci['e_b'][1] / nominal - 1):+.2f} %)")
    print(f"E_max {rounds[0].max_error * 1000:.1f} -> {after.max_error * 1000:.1f} mm: {rounds[0].max_error / after.max_error:.1f}x better")
    if spread is not None:
        verdict = "enough" if args.runs >= spread else "too few"
        print(f"recommended: {spread} runs each way for E_d and E_b within +-{100 * args.tolerance:g} % at 95 % "
              f"(from the spread of round 1's squares; {args.runs} is {verdict})")
    belief = calibrated_belief(robot, final.corrected, ci, scale)
    table = belief_toml(belief, f"ctsim umbmark, seeds {args.seed}-{after.seeds[-1]}")
    print(f"belief (the robot file's [belief] table, in {out / 'belief.toml'}; or --robot-set belief.FIELD=VALUE):")
    print(textwrap.indent(table, "  "), end="")
    figure = write_umbmark_figure(rounds[0], after, {"before": intervals[0]["max_error"], "after": after_interval["max_error"]}, out / "umbmark.png")
    summary = {
        "options": {**robot_options(args), "runs": args.runs, "rounds": args.rounds, "side": args.side, "scale": args.scale, "seed": args.seed, "dt": args.dt},
        "scale": None if scale is None else {"seeds": list(scale.seeds), "length": scale.length, "true": scale.true.tolist(), "counted": scale.counted.tolist(),
                                             "e_s": scale.e_s, "interval": list(scale.interval)},
        "rounds": [_record(r, c) for r, c in zip(rounds, intervals)],
        "after": _record(after, after_interval),
        "calibrated": {"wheel_diameters": [left, right], "track_width": track},
        "recommended_runs": spread,
        "belief": belief,
    }
    with replacing(out / "umbmark.json") as file:
        file.write(json.dumps(summary, indent=1).encode())
    with replacing(out / "belief.toml") as file:
        file.write(table.encode())
    print(f"wrote {figure}, {out / 'umbmark.json'} and {out / 'belief.toml'}")
    return 0


def belief_toml(belief: dict[str, Any], source: str) -> str:
    """`belief` as a robot file's `[belief]` table, saying where it came from."""
    lines = [f"[belief]  # {source}"]
    for key, value in belief.items():
        lines.append(f"{key} = [{value[0]:.6g}, {value[1]:.6g}]" if isinstance(value, list) else f"{key} = {value:.6g}")
    return "\n".join(lines) + "\n"


def _mm(value: float, interval: tuple[float, float]) -> str:
    return f"{value * 1000:.1f} ({interval[0] * 1000:.1f}-{interval[1] * 1000:.1f})"


def _ratio(value: float, interval: tuple[float, float]) -> str:
    return f"{value:.5f} ({interval[0]:.5f}-{interval[1]:.5f})"


def _record(result, interval: dict[str, tuple[float, float]]) -> dict:  # noqa: ANN001 (an UMBmarkResult)
    """One round's figures for umbmark.json (m, rad, ratios)."""
    return {
        "seeds": list(result.seeds), "errors_cw": result.errors_cw.tolist(), "errors_ccw": result.errors_ccw.tolist(),
        "max_error": result.max_error, "e_d": result.e_d, "e_b": result.e_b, "alpha": result.alpha, "beta": result.beta,
        "intervals": {name: list(bounds) for name, bounds in interval.items()},
        "believed": {"wheel_diameters": list(result.believed.wheel_diameters), "track_width": result.believed.track_width},
    }
