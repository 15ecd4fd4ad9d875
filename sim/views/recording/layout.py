"""What a recording holds where: its timeline, the readings fields and sensor plots, how often
trails and ellipses are drawn, the map, and the viewer's blueprint."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from bots.sensor_kinds import BY_FIELD, KINDS, groups
from sim.kinematics.chassis import WheelType
from sim.views import palette
from sim.views.recording.arrow import lazy_rerun
from sim.world.spec import WorldSpec

TIMELINE = "sim_time"
TURNING = (WheelType.STEERED, WheelType.CASTOR, WheelType.SPHERICAL)
"""Wheels whose steering angle changes in a run, and so is recorded."""
TRAIL_EVERY = 10
"""Samples per trail piece: every pose is in the trail, but in 10x fewer rows for the viewer."""
ELLIPSE_EVERY = 200
"""Samples between two uncertainty ellipses along an estimate's trail (2 s at the default step)..."""
ELLIPSE_RECENT_S = 4.0
"""...of which the map shows those of the last this many simulated seconds before the time cursor
(two per estimate): at 300 s all of them would bury the maze and the truth under rings metres wide."""
ELLIPSE_SCALE = math.sqrt(-2.0 * math.log(0.05))
"""Radius, in standard deviations, of the ellipse holding 95 % of a 2-D normal (chi2(2) = 5.99)."""
ELLIPSE_POINTS = 37
FIELDS = tuple(kind.field for kind in KINDS)
"""Readings fields recorded as time series, in buffer column order (the sensor registry's)."""
SENSOR_GROUPS = groups()
"""Sensor plot -> (title, readings fields); each field is logged under sensors/<group>/<robot>/<field>."""
SCALE = {kind.field: kind.scale for kind in KINDS if kind.scale != 1.0}
"""Recorded unit per SI unit where a field is shown in other units (m -> mm, rad -> deg)."""
MAP_MARGIN = 0.03
"""Floor around the world in the map view, as a share of the world's larger side."""
KEY_CHARACTER = 0.009
"""Width of one character of a key label, as a share of the world's larger side (about 7 px at the
map's size in the viewer's default layout): the map is framed on the world and labels keep their
size in pixels, so shares of the world hold them at any world size. The key stands in for the
error plots' legends, which would cover their data."""
KEY_PIXEL = 0.00175
"""One pixel of the map in the viewer's default layout at 1920x1080, as a share of the world's larger
side (measured on screenshots: 40 px per KEY_ROW)."""
KEY_ROW = 0.07
"""Height of one key entry (a swatch, its label centred below it, as rerun draws point labels), as a
share of the world's larger side (about 40 px in the viewer)."""
BAND_LABEL = "3σ bands (thin lines)"
"""The key's entry for the error plots' bands: thin lines in their estimate's colour."""
KEY_EDGE = 1.0
"""Width (points) of the dark rim round each swatch of the key."""
ERROR_LINE = 1.2
"""Width (points) of an estimate's line in the error plots..."""
ERROR_LINE_BENEATH = 4.0
"""...but the first estimate's, drawn beneath the others (rerun draws an entity's series in their
order): an estimate that equals it, as the firmware's (which counts the same ticks) equals the
encoders', shows as a thin line on a wide one in the first's colour instead of hiding it."""


def rgb(rgb: palette.RGB) -> tuple[int, int, int]:
    return tuple(rgb)


def field_channels(spec: Any, name: str) -> tuple[tuple[str, ...], np.ndarray | None]:
    """The channels of readings field `name` that a robot spec has (known before the first
    reading): their names, and which entries of the field they are (None: all of them). A general
    chassis has an encoder per wheel, may have a second mouse, and records the steering of the
    wheels that turn (steered, castors, balls); the c't-Bot has two of each pair."""
    chassis = spec.chassis.chassis if spec.chassis is not None else None
    kind = BY_FIELD[name]
    if chassis is None or not (kind.chassis_only or kind.per_wheel):
        return kind.channels_of(spec), None
    if kind.per_wheel:
        return chassis.names, None
    if not kind.angle:  # a chassis's own device (its second mouse)
        return (kind.channels if kind.present(spec) else ()), None
    turning = np.flatnonzero(np.isin(chassis.kind, TURNING))
    return tuple(chassis.names[i] for i in turning), turning


def ellipses(centres: np.ndarray, entries: np.ndarray) -> np.ndarray:
    """(m, ELLIPSE_POINTS, 2) closed 95 % ellipses of positions `centres` (m, 2) with covariance
    entries (m, 6) (`bots.uncertainty.COVARIANCE_FIELDS`; the position block)."""
    cov = np.stack([np.stack([entries[:, 0], entries[:, 1]], -1), np.stack([entries[:, 1], entries[:, 3]], -1)], -2)
    values, vectors = np.linalg.eigh(cov)
    axes = vectors * (ELLIPSE_SCALE * np.sqrt(np.maximum(values, 0.0)))[:, None, :]  # columns: the scaled axes
    angle = np.linspace(0.0, 2.0 * math.pi, ELLIPSE_POINTS)
    circle = np.stack((np.cos(angle), np.sin(angle)))  # (2, points)
    return centres[:, None, :] + np.einsum("mij,jp->mpi", axes, circle)


def log_world(log: Any, spec: WorldSpec) -> None:
    """Draw a WorldSpec once, as static data under world/map, with `log(path, data, static=True)`:
    the floor as an image of the map's shapes (filled walls, lines at their width), starts."""
    rr = lazy_rerun()
    from sim.views.map_image import map_png

    png, per_metre = map_png(spec)
    xmin, ymin, xmax, ymax = spec.bounds
    # image pixel (u, v) lies at world (xmin + u/s, ymax - v/s): rows run down from the top edge
    log("world/map/floor", rr.Transform3D(translation=(xmin, ymax, 0.0), scale=(1 / per_metre, -1 / per_metre, 1.0)), static=True)
    log("world/map/floor", rr.EncodedImage(contents=png, media_type="image/png", draw_order=-100.0), static=True)
    if spec.starts:
        origins = [(s.x, s.y) for s in spec.starts]
        vectors = [(0.08 * math.cos(s.heading), 0.08 * math.sin(s.heading)) for s in spec.starts]
        log("world/map/starts", rr.Arrows2D(origins=origins, vectors=vectors, colors=rgb(palette.START), radii=-1.5, draw_order=10.0), static=True)


def key_room(spec: WorldSpec, labels: Sequence[str]) -> float:
    """Width (m) the map's key takes right of the world: room for its longest label and a margin,
    at least that of its lines."""
    xmin, ymin, xmax, ymax = spec.bounds
    return max(0.12, 0.05 + KEY_CHARACTER * max(map(len, labels), default=0)) * max(xmax - xmin, ymax - ymin)


def error_widths(estimates: int) -> list[float]:
    """Widths (points) of the error plots' lines of `estimates` estimates, in their order: the
    first wide beneath the rest where there are several (ERROR_LINE_BENEATH)."""
    return [ERROR_LINE_BENEATH if k == 0 and estimates > 1 else ERROR_LINE for k in range(estimates)]


def light_labels(positions: Any, labels: Sequence[str], draw_order: float) -> Any:
    """Points2D that only carry `labels`, in light text (palette.LABEL_TEXT): rerun centres a
    point's label under the point and writes it in the point's colour on a translucent grey box,
    where the colours of series and robots (a red name, a white one) were hard to read. Each point
    is a pixel even at radius 0: draw it beneath what covers it (`draw_order`); its label shows."""
    rr = lazy_rerun()
    return rr.Points2D(positions, colors=rgb(palette.LABEL_TEXT), radii=0.0, labels=list(labels), show_labels=True, draw_order=draw_order)


def log_key(log: Any, spec: WorldSpec, entries: Sequence[tuple[str, palette.RGB, float]]) -> None:
    """Draw the map's colour key once, static under world/map/key, right of the world: per entry
    (label, colour, line radius in points) a swatch, a short line in the entry's colour with a dark
    rim (a white or yellow robot's would fade into the light grey), and hung from its lower edge
    its label in light text (`light_labels`), top down. Its colours and labels are the trails' and
    the error plots' series', whose own legends stay hidden."""
    rr = lazy_rerun()
    xmin, ymin, xmax, ymax = spec.bounds
    size = max(xmax - xmin, ymax - ymin)
    labels, colours, radii = zip(*entries) if entries else ((), (), ())
    row = size * min(KEY_ROW, 1.0 / max(len(entries), 1))  # many robots: rows closer, the key no taller than the world
    centre, half = xmax + MAP_MARGIN * size + 0.5 * key_room(spec, labels), 0.04 * size
    heights = ymax - row * np.arange(len(entries))
    lines = [[(centre - half, y), (centre + half, y)] for y in heights]
    log("world/map/key/lines", rr.LineStrips2D(lines, colors=[rgb(c) for c in colours], radii=[-r for r in radii], draw_order=90.0), static=True)
    log("world/map/key/edges", rr.LineStrips2D(lines, colors=rgb(palette.KEY_EDGE), radii=[-(r + KEY_EDGE) for r in radii], draw_order=89.5), static=True)
    # each label's point lies in its swatch's lower half, beneath it
    anchors = [(centre, y - 0.5 * KEY_PIXEL * r * size) for y, r in zip(heights, radii)]
    log("world/map/key/labels", light_labels(anchors, labels, draw_order=89.0), static=True)


def _error_styles(estimates: Sequence[str], band: str) -> str:
    """What an error plot's lines mean, for its title (its legend is hidden): colours, the wide
    first estimate (`error_widths`), the thin bands."""
    beneath = f"{estimates[0]} wide beneath, " if len(estimates) > 1 else ""
    return f"colours: the map's key, {beneath}thin: {band}"


def blueprint(world: WorldSpec, robots: dict[str, list[str]], groups: list[str], localising: Sequence[str] = (), key: Sequence[str] = ()) -> Any:
    """The map framed on the world and its colour key (labels `key`, see `log_key`) with every
    trail, events and facts below it; per robot its error plots (and, for the robots in
    `localising`, their localisers' scan score and lost flag), and one plot per sensor group in
    `groups`, beside it. `robots` maps each robot's name to its estimates' names."""
    import rerun.blueprint as rrb

    history = rrb.VisibleTimeRanges([rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative())])
    trails = {f"/world/{name}/trail/{label}": history for name, labels in robots.items() for label in ["truth", *labels]}
    recent = rrb.VisibleTimeRanges([rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.cursor_relative(seconds=-ELLIPSE_RECENT_S),
                                                         end=rrb.TimeRangeBoundary.cursor_relative())])  # fmt: skip
    trails |= {f"/world/{name}/ellipse/{label}": recent for name, labels in robots.items() for label in labels}
    xmin, ymin, xmax, ymax = world.bounds
    margin = MAP_MARGIN * max(xmax - xmin, ymax - ymin)
    bounds = rrb.VisualBounds2D(x_range=(xmin - margin, xmax + margin + key_room(world, key)), y_range=(-ymax - margin, -ymin + margin))  # y flipped, see `world`
    world_map = rrb.Spatial2DView(origin="/", contents="+ /world/**", name=f"map: {world.name}", visual_bounds=bounds, background=rgb(palette.BACKGROUND), overrides=trails)
    legend = rrb.PlotLegend(corner=rrb.Corner2D.LeftTop)
    keyed = rrb.PlotLegend(visible=False)  # up to twelve series: the map's key names their colours instead
    errors = [
        rrb.Vertical(
            rrb.TimeSeriesView(origin=f"/errors/{name}/position", name=f"{name}: position error (mm); {_error_styles(estimates, '3σ')}", plot_legend=keyed),
            rrb.TimeSeriesView(origin=f"/errors/{name}/heading", name=f"{name}: heading error (deg); {_error_styles(estimates, '±3σ')}", plot_legend=keyed),
            *([rrb.TimeSeriesView(origin=f"/localisation/{name}", name=f"{name}: scan score (0-1), lost (1)", plot_legend=legend)] if name in localising else []),
            name=f"errors: {name}",
        )
        for name, estimates in robots.items()
        if estimates  # a robot without estimates (a contest's) has no errors to plot
    ]
    shown = [(group, title) for group, (title, _) in SENSOR_GROUPS.items() if group in groups]
    if len(robots) > 1:  # per robot a tab with a plot of each sensor kind: no plot mixes robots
        sensors = [
            rrb.Grid(*(rrb.TimeSeriesView(origin=f"/sensors/{group}/{name}", name=f"{name}: {title}", plot_legend=legend) for group, title in shown), name=f"sensors: {name}")
            for name in robots
        ]
    else:
        sensors = [rrb.TimeSeriesView(origin=f"/sensors/{group}", name=title, plot_legend=legend) for group, title in shown]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                world_map,
                rrb.Tabs(rrb.TextLogView(origin="/events", name="events"), rrb.TextDocumentView(origin="/facts", name="run facts")),
                row_shares=[4, 1],
            ),
            rrb.Vertical(rrb.Tabs(*errors), rrb.Tabs(*sensors), row_shares=[3, 2]) if errors else rrb.Tabs(*sensors),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE),
        collapse_panels=True,
    )
