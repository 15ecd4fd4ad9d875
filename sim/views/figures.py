"""PNG figures of a run: trajectories over the map, and estimate errors over time (matplotlib, Agg).

Works from a run folder as `ctsim run` leaves it (summary.json and TUM files), so that
`ctsim report RUN_DIR` and the report at the end of a run draw the same thing. The map is the
shapes every view draws (`map_image.map_shapes`), here as vector patches.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

import numpy as np

from sim.analysis.export import read_tum, sampled
from sim.analysis.run_folder import RunFolder, RunFolderError, read_summary, trajectory_text
from sim.out_files import replacing
from sim.views import palette
from sim.views.map_image import map_shapes
from sim.world.files.grid import TILE_NAMES
from sim.world.spec import WorldSpec

Trajectory = tuple[np.ndarray, np.ndarray]
"""(times (T,), poses (T, 3))."""

MEAN_WINDOW_S = 1.0
"""Moving mean drawn over the raw error trace (s): encoder quantisation makes a sawtooth."""
MAX_INSETS = 4
"""Robots given a magnified view of their run's end each (the first ones of a larger crowd)."""
DASHES = ("-", (0, (5, 2)), "-", (0, (2, 1.5)), (0, (6, 2, 1, 2)))
"""Estimates often coincide (encoders and firmware, mouse and fused): alternate solid and dashed
lines so that one drawn over another still shows both."""


def _c(rgb: palette.RGB) -> tuple[float, float, float]:
    return palette.unit(rgb)


def draw_world(ax, world: WorldSpec, legend: bool = False) -> None:
    """The map's shapes (`map_image.map_shapes`: ground, floor regions, lines at their true width,
    holes, goals, walls, cans at their start, lights) on matplotlib axes (m), in their order and all
    beneath anything drawn later (zorder < 3)."""
    from matplotlib.patches import Circle, Polygon

    shapes = map_shapes(world)
    for k, shape in enumerate(shapes):
        style = dict(facecolor=_c(shape.fill), edgecolor=_c(shape.edge) if shape.edge else "none", linewidth=shape.edge_pt, zorder=2.5 * k / len(shapes))
        if shape.kind == "polygon":
            ax.add_patch(Polygon(shape.points, **style))
        elif shape.kind == "circle":
            ax.add_patch(Circle(shape.points[0], shape.radius, **style))
        else:
            ax.plot(*shape.points[0], marker="*", markersize=13, color=style["facecolor"], markeredgecolor=style["edgecolor"], zorder=style["zorder"], linestyle="none")
    if legend:
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch

        keys = [("wall", palette.WALL, bool(world.walls)), ("goal", palette.GOAL, bool(world.goals))]
        handles = [Patch(facecolor=world.floor_colour, edgecolor="0.6", label="floor")]
        handles += [Patch(facecolor=colour, edgecolor="0.6", label=TILE_NAMES.get(colour,
                                                                                  f"floor {palette.hex_colour(palette.from_unit(colour))}")) for colour in dict.fromkeys(r.colour for r in world.floor)]
        handles += [Patch(facecolor=_c(rgb), label=label) for label, rgb, present in keys if present]
        handles += [Patch(facecolor=_c(palette.HOLE), edgecolor=_c(palette.HOLE_EDGE), label="hole")] if world.holes else []
        handles += [Patch(facecolor=world.lines[0].colour, label="line")] if world.lines else []
        handles += [Line2D([], [], marker="*", color=_c(palette.LIGHT), linestyle="none", label="light")] if world.lights else []
        ax.add_artist(ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=8, frameon=False, title="map", title_fontsize=8))
    ax.set_aspect("equal")


def _errors(truth: Trajectory, estimate: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, position error m, heading error rad) of an estimate sampled with truth; the heading
    error is unwrapped, so that one that drifts past 180° keeps going instead of jumping."""
    n = min(len(truth[0]), len(estimate[0]))
    diff = estimate[1][:n] - truth[1][:n]
    heading = np.unwrap((diff[:, 2] + np.pi) % (2 * np.pi) - np.pi)
    return truth[0][:n], np.hypot(diff[:, 0], diff[:, 1]), heading


def moving_mean(t: np.ndarray, values: np.ndarray, window_s: float) -> np.ndarray:
    """Centred moving mean over about `window_s` seconds of evenly spaced samples."""
    if len(t) < 3:
        return values
    width = max(1, int(round(window_s / max(np.median(np.diff(t)), 1e-12))))
    width = min(width | 1, len(values) - (1 - len(values) % 2))  # odd, at most the length
    padded = np.pad(values, width // 2, mode="edge")
    return np.convolve(padded, np.ones(width) / width, mode="valid")


def headless_pyplot() -> ModuleType:
    """matplotlib's pyplot on the Agg backend (no window, whatever the machine has): half a second
    to import, which `ctsim bridge` pays in a thread while it waits for its firmware's answers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot

    return matplotlib.pyplot


def write_figures(
    world: WorldSpec,
    robots: dict[str, dict[str, Trajectory]],
    out: str | Path,
    subtitle: str = "",
    ate: dict[str, dict[str, float]] | None = None,
    bands: dict[str, dict[str, Trajectory]] | None = None,
    puts: dict[str, list[float]] | None = None,
) -> list[Path]:
    """`trajectories.png` (every robot's truth and estimates over the map, beside the end of the
    run magnified) and `errors.png` (position and heading error of each estimate over time, and
    its 3 sigma band where it has a covariance) in `out`. `robots` maps a robot name to its
    trajectories by label, 'truth' among them; `ate` the ATE RMS (m) of each estimate by robot,
    shown in the legends; `bands` robot -> label -> (times, (T, 6) covariance entries,
    `bots.uncertainty.COVARIANCE_FIELDS`); `puts` robot -> the times (s) it stood where it was put
    down by hand (`puts_of`), where its truth's line breaks; `subtitle` says what ran."""
    plt = headless_pyplot()
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.lines import Line2D

    out, ate, puts = Path(out), ate or {}, puts or {}
    trajectories_png, errors_png = RunFolder(out).figures
    xmin, ymin, xmax, ymax = world.bounds
    aspect = (ymax - ymin) / max(xmax - xmin, 1e-9)
    several = len(robots) > 1
    colours = palette.robot_colours(list(robots))
    insets = list(robots)[:MAX_INSETS] if several else [None]  # None: the one robot whose estimates part most
    fig = plt.figure(figsize=(12.0, max(4.0, min(6.5 * aspect, 9.0), 2.6 * len(insets)) + 0.8), dpi=120)
    grid = fig.add_gridspec(len(insets), 2, width_ratios=(1.6, 1))
    ax = fig.add_subplot(grid[:, 0])
    zooms = [fig.add_subplot(grid[k, 1]) for k in range(len(insets))]
    for axis in (ax, *zooms):
        draw_world(axis, world, legend=axis is ax)
        for k, (name, tracks) in enumerate(robots.items()):
            _draw_tracks(axis, name if several else "", tracks, {} if several else ate.get(name, {}), colours.get(name, palette.TRUTH), label=axis is ax and (k == 0 or not several),
                         puts=puts.get(name, ()))  # fmt: skip
    ax.autoscale()
    _include(ax, world.bounds)
    ax.set_title(f"{world.name}: trajectories (o start, \u25a0 end)", fontsize=11)
    for zoom, name in zip(zooms, insets):
        factor = _magnify(zoom, ax, robots if name is None else {name: robots[name]})
        title = f"end of the run, magnified \u00d7{factor:.0f}" if name is None else f"{name}: its end, \u00d7{factor:.0f}"
        zoom.set_title(title, fontsize=11 if name is None else 9, **({} if name is None else {"backgroundcolor": _c(colours[name])}))
    for axis in (ax, *zooms):
        axis.set_xlabel("x (m)")
        axis.grid(True, linewidth=0.3, alpha=0.5)
    ax.set_ylabel("y (m)")
    if several:  # a robot's truth in its colour; each estimate's colour once; the ATEs as a table
        from matplotlib.patches import Patch

        handles = [Patch(facecolor=_c(colours[name]), edgecolor="0.2", linewidth=0.5, label=f"{name}: truth") for name in robots]
        handles += [h for h, text in zip(*ax.get_legend_handles_labels()) if not text.endswith("truth")]
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
        if ate:
            ax.text(1.01, 0.55, _ate_table(ate), transform=ax.transAxes, fontsize=7, family="monospace", va="top")
    else:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    if subtitle:
        fig.suptitle(subtitle, fontsize=9, color="0.3", y=0.995)
    fig.tight_layout()
    _fit_height(fig, ax, 2.6 * len(insets) + 0.8)
    written = [_save(fig, trajectories_png)]

    columns = len(robots)  # one column of plots per robot: no plot mixes robots
    fig, axes = plt.subplots(2, columns, figsize=(10.0 if columns == 1 else 4.2 * columns + 2.0, 6.5), dpi=120, sharex=True, sharey="row", squeeze=False)
    for column, (name, tracks) in enumerate(robots.items()):
        top, bottom = axes[:, column]
        keys: list[tuple[tuple[Line2D, Line2D], str]] = []
        for k, (label, estimate) in enumerate(_estimates(tracks)):
            rgb = palette.estimate_colour(label, list(tracks))
            colour, light = _c(rgb), _c(palette.pale(rgb))
            t, position, heading = _errors(tracks["truth"], estimate)
            score = ate.get(name, {}).get(label)
            text = label + (f" (ATE {1000 * score:.1f} mm)" if score is not None else "")
            dashes = DASHES[k % len(DASHES)]
            for axis, values in ((top, position * 1000), (bottom, np.degrees(heading))):
                axis.plot(t, values, color=light, linewidth=0.5, zorder=1 + k / 10)  # opaque: a band shows whose it is
                axis.plot(t, moving_mean(t, values, MEAN_WINDOW_S), color=colour, linewidth=1.6, linestyle=dashes, zorder=3)
            if label in (bands or {}).get(name, {}):
                times, entries = bands[name][label]
                # edged in the estimate's colour: where bands overlap, each edge still says whose it is
                band = {"facecolor": (*light, 0.2), "edgecolor": colour, "linewidth": 0.7, "linestyle": dashes}
                xx, xy, yy, tt = entries[:, 0], entries[:, 1], entries[:, 3], entries[:, 5]
                major = 0.5 * (xx + yy) + np.sqrt(0.25 * (xx - yy) ** 2 + xy**2)  # the position's larger eigenvalue
                top.fill_between(times, 0.0, 3000 * np.sqrt(np.maximum(major, 0.0)), **band)
                spread = 3 * np.degrees(np.sqrt(np.maximum(tt, 0.0)))
                bottom.fill_between(times, -spread, spread, **band)
            keys.append(((Line2D([], [], color=light, linewidth=6), Line2D([], [], color=colour, linewidth=1.6, linestyle=dashes)), text))
        if several:
            top.set_title(name, fontsize=10, backgroundcolor=_c(colours[name]))
        bottom.set_xlabel("simulated time (s)")
        for axis in (top, bottom):
            axis.grid(True, linewidth=0.3, alpha=0.6)
        if keys:  # each estimate's key: its pale band of samples under its moving mean; outside the plots (beside
            # one robot's, under each of several robots' columns), so that no key covers an error
            place = {"loc": "upper center", "bbox_to_anchor": (0.5, -0.16)} if several else {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0)}
            (bottom if several else top).legend([h for h, _ in keys], [text for _, text in keys], handler_map={tuple: HandlerTuple(ndivide=1)},
                                                fontsize=7 if several else 8, frameon=False, **place)
    axes[0, 0].set_ylabel("position error (mm)")
    axes[1, 0].set_ylabel("heading error (deg, unwrapped)")
    title = f"odometry error against ground truth (pale: every sample drawn; dark: {MEAN_WINDOW_S:g} s moving mean; shaded: 3σ)"
    if several:
        fig.text(0.5, 0.955, title, ha="center", fontsize=10)
    else:
        axes[0, 0].set_title(title, fontsize=10)
    if subtitle:
        fig.suptitle(subtitle, fontsize=9, color="0.3", y=0.995)
    fig.tight_layout()
    written.append(_save(fig, errors_png))
    return written


def _draw_tracks(ax, robot: str, tracks: dict[str, Trajectory], ate: dict[str, float], own: palette.RGB, label: bool, puts: Sequence[float] = ()) -> None:
    """Truth (in the robot's `own` colour) and each estimate of one robot, thin and above the map;
    start and end marked, and the start named by `robot` (empty: a lone robot, not named). The
    truth's line breaks before the first sample drawn at or after each of `puts` (s), where a
    hand put the robot down (as the recording's trail: `Recorder._send_trails`; the estimates'
    lines do not)."""
    times, truth = tracks["truth"]
    truth_colour = _c(own)
    drawn = np.insert(truth[:, :2], np.searchsorted(times, puts), np.nan, axis=0)  # (matplotlib breaks a line at a NaN)
    ax.plot(drawn[:, 0], drawn[:, 1], color=truth_colour, linewidth=1.8, alpha=0.9, zorder=4, label="truth" if label else None)
    ax.plot(*truth[0, :2], marker="o", color=truth_colour, markersize=6, zorder=6)
    ax.plot(*truth[-1, :2], marker="s", color=truth_colour, markersize=6, zorder=6)
    if robot:
        ax.annotate(robot, truth[0, :2], xytext=(5, 5), textcoords="offset points", color="black", fontsize=8, weight="bold", zorder=7, annotation_clip=True,
                    bbox={"facecolor": truth_colour, "edgecolor": "none", "alpha": 0.85, "pad": 1.5})  # fmt: skip
    for k, (name, (_, poses)) in enumerate(_estimates(tracks)):
        colour = _c(palette.estimate_colour(name, list(tracks)))
        text = name + (f" (ATE {1000 * ate[name]:.1f} mm)" if name in ate else "")
        ax.plot(poses[:, 0], poses[:, 1], color=colour, linewidth=1.1, linestyle=DASHES[k % len(DASHES)], zorder=5, label=text if label else None)
        ax.plot(*poses[-1, :2], marker="s", color=colour, markersize=4, zorder=6)


def _ate_table(ate: dict[str, dict[str, float]]) -> str:
    """The estimates' ATE RMS (mm) as a small table: a row per estimate, a column per robot."""
    names = list(ate)
    labels = list(dict.fromkeys(label for scores in ate.values() for label in scores))
    width = max(len(n) for n in names) + 1
    rows = ["ATE (mm)  " + "".join(f"{n:>{width}}" for n in names)]
    rows += [f"{label:<10}" + "".join(f"{1000 * ate[n][label]:>{width}.1f}" if label in ate[n] else f"{'':>{width}}" for n in names) for label in labels]
    return "\n".join(rows)


def _magnify(zoom, main, robots: dict[str, dict[str, Trajectory]]) -> float:  # noqa: ANN001 (matplotlib Axes)
    """Frame `zoom` on the robot whose final estimates lie furthest apart; the magnification
    against `main` (at least 2 cm of view, so millimetre differences still show)."""
    from matplotlib.ticker import MaxNLocator

    ends = max((np.array([poses[-1, :2] for _, poses in tracks.values()]) for tracks in robots.values()), key=lambda e: np.ptp(e, axis=0).max())
    centre, half = ends.mean(axis=0), max(0.6 * np.ptp(ends, axis=0).max(), 0.02)
    zoom.set_xlim(centre[0] - half, centre[0] + half)
    zoom.set_ylim(centre[1] - half, centre[1] + half)
    for axis in (zoom.xaxis, zoom.yaxis):  # few ticks: a narrow inset's labels must not run into each other
        axis.set_major_locator(MaxNLocator(nbins=4))
    main.indicate_inset((centre[0] - half, centre[1] - half, 2 * half, 2 * half), inset_ax=None, edgecolor="0.2", linewidth=0.8)
    return float(np.ptp(main.get_xlim()) / (2 * half))


def _include(ax, bounds: tuple[float, float, float, float], margin: float = 0.05) -> None:
    """Limits that show the whole world and every trajectory, even one that strays off the map."""
    xmin, ymin, xmax, ymax = bounds
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    ax.set_xlim(min(x0, xmin) - margin, max(x1, xmax) + margin)
    ax.set_ylim(min(y0, ymin) - margin, max(y1, ymax) + margin)


def _fit_height(fig, ax, least: float) -> None:  # noqa: ANN001 (matplotlib Figure, Axes)
    """Make the figure as tall as the map's equal-aspect axes use (not below `least` inches): a map
    wider than its box leaves empty bands above and below it otherwise."""
    for _ in range(3):  # (the labels' room changes with the height: a few rounds settle it)
        ax.apply_aspect()  # (the position the aspect leaves, without drawing the whole figure)
        width, height = fig.get_size_inches()
        slack = (ax.get_position(original=True).height - ax.get_position().height) * height
        if slack < 0.05 or height <= least:
            return
        fig.set_size_inches(width, max(height - slack, least))
        fig.tight_layout()


def _estimates(tracks: dict[str, Trajectory]) -> list[tuple[str, Trajectory]]:
    return [(label, track) for label, track in tracks.items() if label != "truth"]


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    with replacing(path) as file:  # (never through a link planted in the folder)
        fig.savefig(file, format="png", bbox_inches="tight")
    plt.close(fig)
    return path


def describe(summary: dict) -> str:
    """One line saying what ran: world, controller(s), noise, seed, simulated time, dt."""
    controllers = sorted({robot["controller"] for robot in summary["robots"]})
    return (
        f"world {summary['world']['name']} \u00b7 controller {', '.join(controllers)} \u00b7 noise {summary.get('noise', 'none')} \u00b7 seed {summary['seed']} \u00b7 "
        f"{summary['time']:.1f} s simulated (dt {1000 * summary['dt']:g} ms, {summary['reason']}) \u00b7 ctsim {summary['ctsim_version']}"
    )


def ate_of(summary: dict) -> dict[str, dict[str, float]]:
    """The ATE RMS (m) of each estimate by robot, as the figures' legends show it."""
    return {robot["name"]: {label: e["ate_rmse"] for label, e in robot["estimates"].items() if e.get("ate_rmse") is not None} for robot in summary["robots"]}


def puts_of(summary: dict) -> dict[str, list[float]]:
    """The times (s) each robot was put down by hand (`RobotLog.puts`), by robot (none in a summary
    before them)."""
    return {robot["name"]: robot.get("puts", []) for robot in summary["robots"]}


def report_run_dir(run_dir: str | Path) -> list[Path]:
    """Draw the figures of a run folder written by `ctsim run` into that folder."""
    from sim.world.files import load_world

    run_dir = Path(run_dir)
    summary = read_summary(run_dir)
    world = load_world(summary["world"]["source"])
    robots = {
        robot["name"]: {label: _trajectory(run_dir, name) for label, name in robot.get("tum", {}).items()}
        for robot in summary["robots"]
    }
    if not any(robots.values()):
        raise RunFolderError(RunFolder(run_dir).summary, None, "no trajectories named (robots[].tum): the run wrote none to draw")
    drawn = next((times for tracks in robots.values() for times, _ in tracks.values() if len(times) > 1), None)
    every = round(float(drawn[1] - drawn[0]) / summary["dt"]) if drawn is not None else 1  # (more than 1: a long run's samples thinned, FIGURE_POINTS)
    subtitle = describe(summary) + (f" \u00b7 every {every}th sample drawn" if every > 1 else "")
    return write_figures(world, robots, run_dir, subtitle=subtitle, ate=ate_of(summary), bands=bands_of(run_dir, summary), puts=puts_of(summary))


def _trajectory(run_dir: Path, name: str) -> tuple:
    """A TUM file of the run folder (`run_folder.trajectory_text`: FIGURE_POINTS of its lines at
    most), its content never quoted."""
    text = trajectory_text(run_dir, name, FIGURE_POINTS)
    try:
        return read_tum(io.StringIO(text))
    except ValueError:
        raise RunFolderError(run_dir / name, None, "not a TUM trajectory (8 numbers a line: timestamp tx ty tz qx qy qz qw)") from None


def bands_of(run_dir: Path, summary: dict) -> dict[str, dict[str, Trajectory]]:
    """Robot -> label -> (times, (T, 6) covariance entries) from a run folder's run.parquet
    (none without it, for estimates without a covariance, or from a file Arrow cannot read: the
    bands are an addition to the figures, never a reason to refuse them)."""
    import pyarrow as pa

    path = RunFolder(run_dir).samples
    if path.is_symlink() or not path.is_file():
        return {}
    try:
        return _bands(path, summary)
    except (OSError, pa.ArrowException, KeyError, TypeError, ValueError):
        return {}


FIGURE_POINTS = 200_000
"""Most samples of a trajectory or band a figure draws (evenly spread, the last among them): a
figure has a few thousand pixels across, and a long run's files need not fit in memory."""


def _every_row(file, columns: list[str]):  # noqa: ANN001, ANN202 (pyarrow's ParquetFile and Table)
    """`columns` of every k-th row of a Parquet file and its last, k chosen so that at most about
    FIGURE_POINTS are kept (all where it has no more), read a row group at a time."""
    import pyarrow as pa

    total = file.metadata.num_rows
    every = max(1, -(-total // FIGURE_POINTS))
    if every == 1:
        return file.read(columns=columns)
    parts, start = [], 0
    for group in range(file.num_row_groups):
        part = file.read_row_group(group, columns=columns)
        parts.append(part.take(sampled(slice(start, start + part.num_rows), total, every) - start))
        start += part.num_rows
    return pa.concat_tables(parts)


def _bands(path: Path, summary: dict) -> dict[str, dict[str, Trajectory]]:
    import pyarrow.parquet as pq

    from bots.uncertainty import COVARIANCE_FIELDS as fields

    names = set(pq.read_schema(path).names)
    wanted = {(robot["name"], label) for robot in summary["robots"] for label in robot["estimates"]
              if all(f"{robot['name']}.{label}.{entry}" in names for entry in fields)}  # fmt: skip
    if not wanted:
        return {}
    columns = ["time", *(f"{robot}.{label}.{entry}" for robot, label in sorted(wanted) for entry in fields)]
    table = _every_row(pq.ParquetFile(path), columns)
    times = table.column("time").to_numpy()
    bands: dict[str, dict[str, Trajectory]] = {}
    for robot, label in sorted(wanted):
        entries = np.column_stack([table.column(f"{robot}.{label}.{entry}").to_numpy() for entry in fields])
        bands.setdefault(robot, {})[label] = (times, entries)
    return bands
