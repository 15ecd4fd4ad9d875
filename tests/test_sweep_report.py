"""A sweep's report says what happened: how each run ended (goal reached, time limit, fell, error)
with the goal rate only where a world has a goal, every estimator visible in the figures even
where two of them agree, numbers at their precision and titles that are never cut."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from sim.experiments import Serial, sweep
from sim.experiments.report import OUTCOMES, _title, outcomes, plus_minus, shown_tables, summary_table
from sim.views import palette


def runs(*rows: tuple[str, str, bool, bool]) -> pd.DataFrame:
    """A results table of (world, reason, reached_goal, fell) rows, one estimator's error each."""
    return pd.DataFrame([{"run": k, "world": w, "controller": "c", "seed": k, "until_goal": False, "reason": r, "reached_goal": g, "fell": f,
                          "mouse.ate_rmse": 0.01 * (k + 1)} for k, (w, r, g, f) in enumerate(rows)])  # fmt: skip


def test_each_run_counts_once_as_what_happened_to_it():
    table = runs(("maze", "duration", False, False), ("maze", "goal", True, False), ("maze", "error", False, False),
                 ("maze", "duration", False, True), ("maze", "duration", True, True), ("maze", "done", False, False))  # fmt: skip
    assert list(outcomes(table)) == ["time limit", "goal reached", "error", "fell", "goal reached", "controller done"]


def test_runs_that_all_ran_out_of_time_read_as_such_not_as_successes():
    """200 maze runs that hit the time limit: 0 % goal, 200 'time limit'; a world without a goal
    has no goal rate at all."""
    table = runs(*[("maze", "duration", False, False)] * 200, *[("empty", "duration", False, False)] * 3)
    summary = summary_table(table, ["world"]).set_index("world")
    assert summary.loc["maze", "time limit"] == 200 and summary.loc["maze", "goal reached"] == 0 and summary.loc["maze", "goal_%"] == 0.0
    assert math.isnan(summary.loc["empty", "goal_%"])
    ended = shown_tables(summary_table(table, ["world"]))
    (first, shown), *_ = ended.items()
    assert "each run counted once" in first and list(shown["goal rate"]) == ["– (no goal)", "0 %"]


def test_the_goal_rate_counts_the_runs_that_reached_it():
    table = runs(("maze", "goal", True, False), ("maze", "duration", False, False), ("maze", "duration", False, False), ("maze", "error", False, False))
    summary = summary_table(table, [])
    assert summary.loc[0, "goal_%"] == pytest.approx(25.0) and [summary.loc[0, k] for k in OUTCOMES] == [1, 2, 0, 1, 0]


@pytest.mark.parametrize(
    "mean, std, text",
    [(0.11623, 0.04801, "0.116 ± 0.048"), (100.0, 0.0, "100"), (0.00153042, 2.7e-19, "0.00153"), (12.345, 1.5, "12.3 ± 1.5"),
     (0.5, math.nan, "0.5"), (math.nan, math.nan, "–"), (1234.5, 250.0, "1234 ± 250")],  # fmt: skip
)
def test_numbers_are_shown_at_their_precision(mean, std, text):
    """Two significant digits of the spread, the mean to the same place; no spread (one run, or
    one below rounding), three significant digits."""
    assert plus_minus(mean, std) == text


def test_a_long_title_is_wrapped_inside_its_figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.0, 3.0))
    note = "pooled over " + ", ".join(f"robot.encoders.setting_{k} (5 values)" for k in range(8))
    _title(ax, "ate_rmse against robot.mouse.noise_std", note)
    fig.tight_layout()
    fig.canvas.draw()
    title = ax.title.get_window_extent(fig.canvas.get_renderer())
    plt.close(fig)
    assert title.x0 >= 0 and title.x1 <= fig.bbox.x1 and title.y1 <= fig.bbox.y1  # (all of it inside the figure)


def _pixels_of(png, rgb: tuple[int, int, int]) -> int:
    import matplotlib.image

    image = (matplotlib.image.imread(png)[..., :3] * 255).round().astype(int)
    return int((image == rgb).all(axis=-1).sum())


def test_two_estimators_that_agree_both_show_against_a_setting(tmp_path):
    """Without a mouse error the encoders and the firmware estimate alike: each still has its
    colour in the figure (a marker and a dash of its own), and the page prints no 100.0000."""
    from sim.web.report import write_sweep_report

    table = sweep({"base": {"duration": 1.0, "world": "empty", "controller": "wander"}, "axes": {"seed": [0, 1], "robot.encoders.slip_std": [0.0, 0.02]}},
                  tmp_path / "out", Serial(), progress=False)  # fmt: skip
    assert np.allclose(table["encoders.ate_rmse"], table["firmware.ate_rmse"], atol=1e-3)  # (the firmware integrates the same ticks)
    paths = write_sweep_report(tmp_path / "out")
    figure = tmp_path / "out" / "figures" / "ate_rmse_vs_robot.encoders.slip_std.png"
    for name in ("encoders", "firmware", "mouse", "fused"):
        assert _pixels_of(figure, palette.estimate_colour(name)) > 30, name
    page = paths[-1].read_text()
    assert "100.0000" not in page and "goal reached" in page and "time limit" in page
