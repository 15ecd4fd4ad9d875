"""PNG figures of a run: trajectories over the map, and estimate errors over time (matplotlib, Agg).

Works from a run folder as `ctsim run` leaves it (summary.json and TUM files), so that
`ctsim report RUN_DIR` and the report at the end of a run draw the same thing.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sim.analysis.export import read_tum
from sim.world.spec import WorldSpec

Trajectory = tuple[np.ndarray, np.ndarray]
"""(times (T,), poses (T, 3))."""

TRUTH_STYLE = dict(color="#1e9c3c", linewidth=3.0, alpha=0.8, label="truth", zorder=4)
ESTIMATE_STYLES = tuple(
    dict(color=colour, linestyle=dash, linewidth=width)
    for colour, dash, width in (
        ("#e6781e", "-", 2.2),
        ("#2868dc", (0, (4, 2)), 1.6),
        ("#aa3cbe", "-", 2.2),
        ("#14a096", (0, (4, 2)), 1.6),
        ("#c8283c", (0, (1, 1.5)), 1.6),
    )
)
"""Estimates often coincide (encoders and firmware, mouse and fused): alternate solid and dashed
lines so that one drawn over another still shows both."""


def draw_world(ax, world: WorldSpec) -> None:
    """Walls, floor regions, lines, holes, goals, cans (at their start) and lights of a world on
    matplotlib axes (m)."""
    from matplotlib.patches import Circle, Polygon

    xmin, ymin, xmax, ymax = world.bounds
    ax.add_patch(Polygon([(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)], facecolor=world.floor_colour, alpha=0.25, edgecolor="0.5", zorder=0))
    for region in world.floor:
        ax.add_patch(Polygon(region.vertices, facecolor=region.colour, alpha=0.45, edgecolor="none", zorder=1))
    for line in world.lines:
        points = np.asarray(line.points)
        ax.plot(points[:, 0], points[:, 1], color=line.colour, linewidth=2.0, solid_capstyle="butt", zorder=2)
    for hole in world.holes:
        ax.add_patch(Polygon(hole.vertices, facecolor="black", edgecolor="black", zorder=2))
    for goal in world.goals:
        ax.add_patch(Polygon(goal.vertices, facecolor="#7be38f", alpha=0.6, edgecolor="#2a9c45", zorder=2))
    for wall in world.walls:
        ax.add_patch(Polygon(wall.vertices, facecolor="#5a5a5a", edgecolor="#3a3a3a", linewidth=0.5, zorder=3))
    for can in world.movables:
        ax.add_patch(Circle(can.position, can.radius, facecolor="#c8782a", edgecolor="#6b3c10", linewidth=0.5, zorder=3))
    for light in world.lights:
        ax.plot(*light.position, marker="*", markersize=14, color="#ffd21e", markeredgecolor="#a08000", zorder=4)
    ax.set_aspect("equal")


def _errors(truth: Trajectory, estimate: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, position error m, wrapped heading error rad) of an estimate sampled with truth."""
    n = min(len(truth[0]), len(estimate[0]))
    diff = estimate[1][:n] - truth[1][:n]
    heading = (diff[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return truth[0][:n], np.hypot(diff[:, 0], diff[:, 1]), heading


def write_figures(world: WorldSpec, robots: dict[str, dict[str, Trajectory]], out: str | Path) -> list[Path]:
    """`trajectories.png` (every robot's truth and estimates over the map) and `errors.png`
    (position and heading error of each estimate over time) in `out`. `robots` maps a robot
    name to its trajectories by label, 'truth' among them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    written = []
    xmin, ymin, xmax, ymax = world.bounds
    aspect = (ymax - ymin) / max(xmax - xmin, 1e-9)
    fig, ax = plt.subplots(figsize=(8.0, max(3.0, min(8.0 * aspect, 10.0)) + 0.6), dpi=120)
    draw_world(ax, world)
    several = len(robots) > 1
    for name, tracks in robots.items():
        prefix = f"{name}: " if several else ""
        t, truth = tracks["truth"]
        ax.plot(truth[:, 0], truth[:, 1], **{**TRUTH_STYLE, "label": prefix + "truth"})
        ax.plot(*truth[0, :2], marker="o", color=TRUTH_STYLE["color"], markersize=7, zorder=6)
        ax.plot(*truth[-1, :2], marker="s", color=TRUTH_STYLE["color"], markersize=7, zorder=6)
        for (label, (_, poses)), style in zip(_estimates(tracks), ESTIMATE_STYLES):
            ax.plot(poses[:, 0], poses[:, 1], **style, label=prefix + label, zorder=5)
            ax.plot(*poses[-1, :2], marker="s", color=style["color"], markersize=6, zorder=6)
    ax.autoscale()
    _include(ax, world.bounds)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{world.name}: trajectories (o start, \u25a0 end)")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
    ax.grid(True, linewidth=0.3, alpha=0.5)
    fig.tight_layout()
    written.append(_save(fig, out / "trajectories.png"))

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8.0, 6.0), dpi=120, sharex=True)
    for name, tracks in robots.items():
        prefix = f"{name}: " if several else ""
        for (label, estimate), style in zip(_estimates(tracks), ESTIMATE_STYLES):
            t, position, heading = _errors(tracks["truth"], estimate)
            top.plot(t, position * 1000, **style, label=prefix + label)
            bottom.plot(t, np.degrees(heading), **style, label=prefix + label)
    top.set_ylabel("position error (mm)")
    bottom.set_ylabel("heading error (deg)")
    bottom.set_xlabel("simulated time (s)")
    top.set_title("odometry error against ground truth")
    for axis in (top, bottom):
        axis.grid(True, linewidth=0.3, alpha=0.6)
        if axis.get_legend_handles_labels()[0]:
            axis.legend(fontsize=9, loc="upper left")
    fig.tight_layout()
    written.append(_save(fig, out / "errors.png"))
    return written


def _include(ax, bounds: tuple[float, float, float, float], margin: float = 0.05) -> None:
    """Limits that show the whole world and every trajectory, even one that strays off the map."""
    xmin, ymin, xmax, ymax = bounds
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    ax.set_xlim(min(x0, xmin) - margin, max(x1, xmax) + margin)
    ax.set_ylim(min(y0, ymin) - margin, max(y1, ymax) + margin)


def _estimates(tracks: dict[str, Trajectory]) -> list[tuple[str, Trajectory]]:
    return [(label, track) for label, track in tracks.items() if label != "truth"]


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return path


def report_run_dir(run_dir: str | Path) -> list[Path]:
    """Draw the figures of a run folder written by `ctsim run` into that folder."""
    from sim.world.files import load_world

    run_dir = Path(run_dir)
    summary_path = run_dir / "summary.json"
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise ValueError(f"{summary_path}:{err.lineno}: {err.msg}") from None
    world = load_world(summary["world"]["source"])
    robots = {
        robot["name"]: {label: read_tum(run_dir / name) for label, name in robot["tum"].items()}
        for robot in summary["robots"]
    }
    return write_figures(world, robots, run_dir)
