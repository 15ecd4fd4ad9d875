"""The PNG figure of `ctsim umbmark`: each square's return error before and after the calibration,
their centres of gravity and E_max (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.analysis.umbmark import UMBmarkResult
from sim.out_files import replacing
from sim.views import palette

DIRECTIONS = {"cw": palette.ESTIMATES["firmware"], "ccw": palette.ESTIMATES["encoders"]}
"""One colour per direction, before and after alike (blue clockwise, orange counter-clockwise)."""


def write_umbmark_figure(before: UMBmarkResult, after: UMBmarkResult, intervals: dict[str, tuple[float, float]], path: Path) -> Path:
    """Return errors (mm, start frame) of the squares `before` (dots) and `after` (crosses) the
    calibration, each direction's centre of gravity (large), and E_max as a circle about the
    start with its interval (`intervals`: "before" and "after", m) in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    fig, ax = plt.subplots(figsize=(10.0, 6.5))
    for result, when, marker, fill in ((before, "before", "o", 0.35), (after, "after", "x", 0.8)):
        low, high = intervals[when]
        for name, errors, cg in (("cw", result.errors_cw, result.cg_cw), ("ccw", result.errors_ccw, result.cg_ccw)):
            colour = palette.unit(DIRECTIONS[name])
            ax.plot(*(errors * 1000).T, marker, color=colour, alpha=fill, markersize=4, linestyle="none",
                    label=f"{name} {when} ({len(errors)} squares)")
            ax.plot(*(cg * 1000), marker="o" if when == "before" else "X", color=colour, markeredgecolor="black", markersize=11, linestyle="none")
        ax.add_patch(Circle((0, 0), result.max_error * 1000, fill=False, linestyle="--" if when == "before" else "-", color="0.25",
                            label=f"E_max {when} {result.max_error * 1000:.1f} mm (95 % CI {low * 1000:.1f}-{high * 1000:.1f})"))
    ax.plot(0, 0, "+", color="black", markersize=14, label="odometry's end (every square)")
    extent = 1000 * max(np.abs(np.concatenate((before.errors_cw, before.errors_ccw))).max(), before.max_error) * 1.1
    ax.set_xlim(-extent, extent)
    ax.set_ylim(-extent, extent)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("return error x (mm, along the first leg)")
    ax.set_ylabel("return error y (mm, to its left)")
    ax.set_title(f"UMBmark, {before.side:g} m squares: true end minus odometry's end\n"
                 f"E_max {before.max_error * 1000:.1f} -> {after.max_error * 1000:.1f} mm "
                 f"({before.max_error / after.max_error:.1f}x); large markers: centres of gravity")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, framealpha=0.9)
    with replacing(path) as file:  # (never through a link planted in the folder)
        fig.savefig(file, format="png", bbox_inches="tight", dpi=110)
    plt.close(fig)
    return path
