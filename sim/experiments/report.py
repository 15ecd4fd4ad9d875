"""The report of a sweep, grouped by the settings the user names (default: every swept one but the
seed): a summary table per group (CSV and terminal) of how the runs ended (goal reached, time
limit, fell, error) and each estimator's error, error distributions per estimator, error against
each numeric setting with 95 % confidence bands, and how the runs ended per group (PNG,
matplotlib, headless); every figure and the table say what they pool over.

    ctsim sweep report runs/noise --by robot.encoders.slip_std    # or: write_report("runs/noise", by=[...])
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sim.analysis.nees import over_runs
from sim.errors import UserError
from sim.experiments import store
from sim.experiments.plan import DEFAULTS
from sim.out_files import replacing
from sim.views import palette

METRIC = "ate_rmse"
"""The error the figures show: RMS absolute trajectory error (m)."""
Z95 = 1.96
"""Normal quantile of a two-sided 95 % interval of a mean."""


def estimators(table: pd.DataFrame, metric: str = METRIC) -> list[str]:
    """Estimator names with a `<estimator>.<metric>` column, in table order."""
    return [c.removesuffix(f".{metric}") for c in table.columns if c.endswith(f".{metric}") and not c.startswith(("robot.", "params."))]


def swept(table: pd.DataFrame) -> list[str]:
    """Setting columns with more than one value: the sweep's parameters."""
    settings = [c for c in table.columns if c in DEFAULTS or c.startswith(("robot.", "params."))]
    return [c for c in settings if table[c].astype(str).nunique() > 1]


def mean_band(table: pd.DataFrame, by: str, column: str) -> pd.DataFrame:
    """Mean of `column` per value of `by`, with the half-width of its 95 % confidence interval
    (normal approximation, 1.96 standard errors; 0 for a single run)."""
    grouped = table.groupby(by, sort=True)[column]
    frame = pd.DataFrame({"mean": grouped.mean(), "sem": grouped.sem(ddof=1).fillna(0.0), "n": grouped.count()})
    frame["half_width"] = Z95 * frame["sem"]
    return frame


OUTCOMES = ("goal reached", "time limit", "fell", "error", "controller done")
"""How a run ended, each run counted once, the first that holds: `error` (a controller failed or
its worker was lost), `goal reached` (a goal area, at any time), `fell` (into a hole), `time
limit` (it ran its whole duration), `controller done` (every controller said it was done)."""


def outcomes(table: pd.DataFrame) -> pd.Series:
    """Per run, how it ended (one of OUTCOMES)."""
    goal = table["reached_goal"].fillna(False).astype(bool)
    fell = table["fell"].fillna(False).astype(bool)
    reason = table["reason"]
    kinds = np.select([reason == "error", goal, fell, reason == "duration"], ["error", "goal reached", "fell", "time limit"], default="controller done")
    return pd.Series(kinds, index=table.index)


def goal_worlds(table: pd.DataFrame) -> set[str]:
    """The sweep's worlds that have a goal area (a world whose file cannot be read any more counts
    as one where a run reached a goal)."""
    from sim.experiments.api import world

    found = set()
    for name in table["world"].astype(str).unique():
        try:
            if world(name).goals:
                found.add(name)
        except (UserError, OSError):
            if table.loc[table["world"].astype(str) == name, "reached_goal"].fillna(False).astype(bool).any():
                found.add(name)
    return found


class ReportError(UserError):
    """A report asked of a folder or by axes that cannot give one; the message says which."""


def grouping(table: pd.DataFrame, by: list[str] | None = None) -> tuple[list[str], list[str]]:
    """(axes the report groups by, swept axes it pools over): `by` as named (default: every swept
    setting but the seed), the other swept settings pooled."""
    varied = swept(table)
    if by is None:
        by = [c for c in varied if c != "seed"]
    unknown = [b for b in by if b not in table.columns or not (b in DEFAULTS or b.startswith(("robot.", "params.")))]
    if unknown:
        raise ReportError(f"no setting {', '.join(map(repr, unknown))} in this sweep (its settings: {', '.join(c for c in table.columns if c in DEFAULTS or c.startswith(('robot.', 'params.')))})")
    return list(by), [c for c in varied if c not in by]


def pooled_note(table: pd.DataFrame, pooled: list[str]) -> str:
    """What a figure or table pools, in words: 'pooled over seed (5 values), world (2 values)'."""
    if not pooled:
        return "nothing pooled: one setting per group"
    return "pooled over " + ", ".join(f"{c} ({table[c].astype(str).nunique()} values)" for c in pooled)


NEES = "nees_final"
"""Each run's NEES at its end: averaged over a group's runs and judged against the chi-square
interval of that many runs (`sim.analysis.nees.over_runs`)."""


def summary_table(table: pd.DataFrame, by: list[str] | None = None, metric: str = METRIC) -> pd.DataFrame:
    """One row per combination of the `by` settings: runs, how many ended each way (OUTCOMES), the
    share that reached the goal (`goal_%`, over the runs in worlds with a goal; NaN where none
    has one), and mean, standard deviation and count of `metric` per estimator over the runs
    without error; for an estimator with a covariance, the mean NEES at the runs' end, its 95 %
    interval for that many runs and the verdict (`<estimator>.nees.mean`, `.runs`, `.low`,
    `.high`, `.verdict`)."""
    by, _ = grouping(table, by)
    names = estimators(table, metric)
    with_goal = goal_worlds(table)
    frame = table.assign(_outcome=outcomes(table), _goal_world=table["world"].astype(str).isin(with_goal), _all="all runs")
    keys = by or ["_all"]
    rows = []
    for values, group in frame.groupby(keys, sort=True, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        row = dict(zip(by, values)) if by else {"runs of": "all"}
        row["runs"] = len(group)
        row.update({kind: int((group["_outcome"] == kind).sum()) for kind in OUTCOMES})
        aimed = group[group["_goal_world"]]
        row["goal_%"] = 100.0 * float((aimed["_outcome"] == "goal reached").mean()) if len(aimed) else np.nan
        finished = group[group["_outcome"] != "error"]
        for name in names:
            column = finished[f"{name}.{metric}"].dropna()
            row.update({f"{name}.{metric}.mean": column.mean(), f"{name}.{metric}.std": column.std(), f"{name}.{metric}.n": len(column)})
            if f"{name}.{NEES}" in finished:
                judged = over_runs(finished[f"{name}.{NEES}"].to_numpy(dtype=float))
                row.update({f"{name}.nees.mean": judged.mean, f"{name}.nees.runs": judged.runs, f"{name}.nees.low": judged.low,
                            f"{name}.nees.high": judged.high, f"{name}.nees.verdict": judged.verdict})  # fmt: skip
        rows.append(row)
    return pd.DataFrame(rows)


def plus_minus(mean: float, std: float) -> str:
    """'0.116 ± 0.048': the standard deviation to two significant digits and the mean to the same
    place; a mean alone (one run, or no spread beyond rounding: a billionth of it) to three
    significant digits."""
    if not np.isfinite(mean):
        return "–"
    if not (np.isfinite(std) and std > 1e-9 * abs(mean)):
        return f"{mean:.3g}"
    places = max(0, 1 - int(np.floor(np.log10(std))))
    return f"{mean:.{places}f} ± {std:.{places}f}"


def setting(value: object) -> str:
    """A setting's value as written in a spec: 0.02, not 0.020000."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def shown_tables(summary: pd.DataFrame, metric: str = METRIC) -> dict[str, pd.DataFrame]:
    """`summary_table` as text for people, in parts narrow enough to read: how the runs ended,
    each estimator's `metric` (mean ± standard deviation over the runs without error), and where
    an estimator has a covariance its NEES over the runs (mean, 95 % interval of that many runs,
    verdict). Keyed by each part's heading; the settings of a row start every part."""
    keys = [c for c in summary.columns if c == "runs of" or c in DEFAULTS or c.startswith(("robot.", "params."))]
    first = summary[keys].map(setting)
    ended = first.assign(runs=summary["runs"])
    for kind in OUTCOMES:
        if kind != "controller done" or summary[kind].any():  # (rare: shown where it happened)
            ended[kind] = summary[kind]
    ended["goal rate"] = [f"{v:.0f} %" if np.isfinite(v) else "– (no goal)" for v in summary["goal_%"]]
    names = [c.removesuffix(f".{metric}.mean") for c in summary.columns if c.endswith(f".{metric}.mean")]
    errors = first.assign(**{name: [plus_minus(m, s) for m, s in zip(summary[f"{name}.{metric}.mean"], summary[f"{name}.{metric}.std"])] for name in names})
    parts = {"How the runs ended (each run counted once: error, else goal reached, else fell, else time limit)": ended,
             f"{metric} (m) per estimator, mean ± standard deviation over the runs without error": errors}  # fmt: skip
    judged = [c.removesuffix(".nees.mean") for c in summary.columns if c.endswith(".nees.mean")]
    if judged:
        bounds = {(low, high) for name in judged for low, high, runs in zip(summary[f"{name}.nees.low"], summary[f"{name}.nees.high"], summary[f"{name}.nees.runs"]) if runs}
        alike = len(bounds) == 1  # (every group as many runs: one interval, said once in the heading)
        interval = f"its 95 % interval {next(iter(bounds))[0]:.2f}–{next(iter(bounds))[1]:.2f} for that many runs" if alike else "in its 95 % interval for that many runs"
        parts[f"NEES at the runs' end per estimator: mean over the runs, {interval}, verdict"] = first.assign(**{
            name: ["–" if not runs else f"{m:.3g}: {verdict}" if alike else f"{m:.3g} in {low:.2f}–{high:.2f}: {verdict}" for m, runs, low, high, verdict in
                   zip(summary[f"{name}.nees.mean"], summary[f"{name}.nees.runs"], summary[f"{name}.nees.low"], summary[f"{name}.nees.high"], summary[f"{name}.nees.verdict"])]
            for name in judged})  # fmt: skip
    return parts


def write_report(out: str | Path, metric: str = METRIC, by: list[str] | None = None) -> list[Path]:
    """The sweep in `out` grouped by the `by` settings (default: every swept one but the seed):
    `out/summary.csv` (`summary_table`) and figures in `out/figures/`, each titled with what it
    pools over; the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    table = store.load(out)
    if table.empty:
        raise ReportError(f"{out}: no finished runs to report on")
    by, pooled = grouping(table, by)
    folder = out / "figures"
    folder.mkdir(exist_ok=True)
    summary_table(table, by, metric).to_csv(out / "summary.csv", index=False)
    written = [out / "summary.csv"]
    names = estimators(table, metric)
    finished = table[table["reason"] != "error"]
    groups = [c for c in by if not pd.api.types.is_numeric_dtype(finished[c])] if len(finished) else []
    if names and len(finished):
        parts = list(finished.groupby(groups, sort=True)) if groups else [((), finished)]
        fig, ax = plt.subplots(figsize=(min(16.0, max(6.5, 0.32 * len(parts) * len(names) + 2.5)), 4.8))
        for k, name in enumerate(names):  # each group's boxes side by side, each estimator in its colour of the run figures and the viewer
            rgb = palette.estimate_colour(name, names)
            where = np.arange(len(parts)) * (len(names) + 1) + k
            boxes = ax.boxplot([part[f"{name}.{metric}"].dropna().to_numpy() for _, part in parts], positions=where, widths=0.75, showmeans=True,
                               patch_artist=True, manage_ticks=False, meanprops={"marker": "^", "markerfacecolor": "white", "markeredgecolor": "0.2"},  # (not truth's green)
                               flierprops={"markeredgecolor": palette.unit(rgb)})  # fmt: skip
            for box in boxes["boxes"]:
                box.set(facecolor=palette.unit(palette.pale(rgb)), edgecolor=palette.unit(rgb))
            for line in (*boxes["medians"], *boxes["whiskers"], *boxes["caps"]):
                line.set(color=palette.unit(rgb), linewidth=1.6 if line in boxes["medians"] else 1.0)
            boxes["boxes"][0].set_label(name)
        centres = np.arange(len(parts)) * (len(names) + 1) + (len(names) - 1) / 2
        ax.set_xticks(centres, ["\n".join(map(str, key if isinstance(key, tuple) else (key,))) for key, _ in parts] if groups else ["all runs"], fontsize=8)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="estimator", title_fontsize=8)
        ax.set_ylabel(f"{metric} (m)")
        _title(ax, f"{metric} per estimator" + (f" and {', '.join(groups)}" if groups else "") + f", {len(finished)} runs",
               pooled_note(finished, [c for c in (*pooled, *by) if c not in groups and c in swept(finished)]))
        written.append(_save(fig, folder / f"{metric}_per_estimator.png"))
        for parameter in by:
            if not pd.api.types.is_numeric_dtype(finished[parameter]) or finished[parameter].nunique() < 2:
                continue
            fig, ax = plt.subplots(figsize=(6.5, 4.5))
            for k, name in enumerate(names):
                band = mean_band(finished, parameter, f"{name}.{metric}")
                x = band.index.to_numpy(dtype=float)
                rgb = palette.estimate_colour(name, names)
                # a marker and a dash of its own, smaller for each later estimator: two estimators with
                # the same means (the encoders' and the firmware's, often) still both show
                ax.plot(x, band["mean"], color=palette.unit(rgb), label=name, zorder=3 + k, marker=MARKERS[k % len(MARKERS)],
                        markersize=max(3.0, 10.0 - 2.0 * k), linestyle=DASHES[k % len(DASHES)], linewidth=max(1.0, 2.6 - 0.5 * k))  # fmt: skip
                # the band edged in its estimator's colour: overlapping bands still say whose they are
                ax.fill_between(x, band["mean"] - band["half_width"], band["mean"] + band["half_width"], facecolor=(*palette.unit(palette.pale(rgb)), 0.3),
                                edgecolor=palette.unit(rgb), linewidth=0.8, linestyle="--")
            ax.set_xlabel(parameter)
            ax.set_ylabel(f"mean {metric} (m), 95 % band")
            _title(ax, f"{metric} against {parameter}", pooled_note(finished, [c for c in swept(finished) if c != parameter]))
            ax.legend()
            written.append(_save(fig, folder / f"{metric}_vs_{parameter}.png"))
    written.append(_outcome_figure(table, by, pooled, folder))
    return written


def _outcome_figure(table: pd.DataFrame, by: list[str], pooled: list[str], folder: Path) -> Path:
    """outcomes.png: per group of the `by` settings a bar of its runs split by how they ended
    (OUTCOMES, each in its colour, counts written in), the goal rate beside it where its worlds
    have a goal."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    summary = summary_table(table, by)
    labels = [", ".join(setting(v) for v in values) for values in summary[by].itertuples(index=False)] if by else ["all runs"]
    fig, ax = plt.subplots(figsize=(9.0, 1.6 + 0.42 * len(summary)))
    left = np.zeros(len(summary))
    y = np.arange(len(summary))[::-1]
    for kind in OUTCOMES:
        counts = summary[kind].to_numpy(dtype=float)
        if not counts.any():
            continue
        bars = ax.barh(y, counts, left=left, color=palette.unit(palette.OUTCOMES[kind]), label=kind, height=0.7)
        ax.bar_label(bars, labels=[f"{c:.0f}" if c else "" for c in counts], label_type="center", color="white", fontsize=8)
        left += counts
    for k, rate in enumerate(summary["goal_%"]):
        if np.isfinite(rate):
            ax.text(left[k], y[k], f"  goal {rate:.0f} %", va="center", fontsize=8)
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_xlim(0, left.max() * 1.18)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("runs")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="ended by", title_fontsize=8)
    _title(ax, "how the runs ended, per " + (", ".join(by) or "sweep"), pooled_note(table, pooled))
    return _save(fig, folder / "outcomes.png")


MARKERS = ("o", "s", "^", "D", "v", "P")
DASHES = ("-", "--", "-.", ":")
"""Each estimator's marker and line style in the figures against a setting, by its place."""


def _title(ax, first: str, note: str, fontsize: float = 9) -> None:  # noqa: ANN001 (a matplotlib Axes)
    """A figure's title and the note under it, wrapped to the figure's width (never cut)."""
    import textwrap

    width = int(ax.figure.get_figwidth() * 72 / (0.55 * fontsize))  # characters of about 0.55 em
    ax.set_title("\n".join([*textwrap.wrap(first, width), *textwrap.wrap(note, width)]), fontsize=fontsize)


def _save(fig, path: Path) -> Path:  # noqa: ANN001 (a matplotlib Figure)
    import matplotlib.pyplot as plt

    fig.tight_layout()
    with replacing(path) as file:  # (never through a link planted in the folder)
        fig.savefig(file, format="png", dpi=110)
    plt.close(fig)
    return path


def terminal_table(summary: pd.DataFrame, metric: str = METRIC) -> str:
    """`summary_table` for a terminal: the parts of `shown_tables`, each under its heading."""
    return "\n\n".join(f"{heading}:\n{part.to_string(index=False)}" for heading, part in shown_tables(summary, metric).items())
