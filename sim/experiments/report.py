"""The report of a sweep, grouped by the settings the user names (default: every swept one but the
seed): a summary table per group (CSV and terminal), error distributions per estimator, error
against each numeric setting with 95 % confidence bands, and success rate per controller (PNG,
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
from sim.run.ending import Ending
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


def success(table: pd.DataFrame) -> pd.Series:
    """Per run: it ended without error and without falling, and reached a goal where it was asked to."""
    ok = (table["reason"] != Ending.ERROR) & ~table["fell"].fillna(False).astype(bool)
    return ok & (table["reached_goal"].fillna(False).astype(bool) | ~table["until_goal"].astype(bool))


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
    """One row per combination of the `by` settings: runs, failed runs, success rate (%), and mean,
    standard deviation and count of `metric` per estimator over the runs that did not fail; for
    an estimator with a covariance, the mean NEES at the runs' end, its 95 % interval for that
    many runs and the verdict (`<estimator>.nees.mean`, `.runs`, `.low`, `.high`, `.verdict`)."""
    by, _ = grouping(table, by)
    names = estimators(table, metric)
    frame = table.assign(_ok=success(table), _failed=table["reason"] == Ending.ERROR, _all="all runs")
    keys = by or ["_all"]
    rows = []
    for values, group in frame.groupby(keys, sort=True, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        row = dict(zip(by, values)) if by else {"runs of": "all"}
        row.update({"runs": len(group), "failed": int(group["_failed"].sum()), "success_%": 100.0 * group["_ok"].mean()})
        finished = group[~group["_failed"]]
        for name in names:
            column = finished[f"{name}.{metric}"].dropna()
            row.update({f"{name}.{metric}.mean": column.mean(), f"{name}.{metric}.std": column.std(), f"{name}.{metric}.n": len(column)})
            if f"{name}.{NEES}" in finished:
                judged = over_runs(finished[f"{name}.{NEES}"].to_numpy(dtype=float))
                row.update({f"{name}.nees.mean": judged.mean, f"{name}.nees.runs": judged.runs, f"{name}.nees.low": judged.low,
                            f"{name}.nees.high": judged.high, f"{name}.nees.verdict": judged.verdict})  # fmt: skip
        rows.append(row)
    return pd.DataFrame(rows)


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
    finished = table[table["reason"] != Ending.ERROR]
    groups = [c for c in by if not pd.api.types.is_numeric_dtype(finished[c])] if len(finished) else []
    if names and len(finished):
        labels, data, colours = [], [], []
        parts = finished.groupby(groups, sort=True) if groups else [((), finished)]
        for key, part in parts:
            key = key if isinstance(key, tuple) else (key,)
            for n in names:
                labels.append("\n".join([n, *map(str, key)]))
                data.append(part[f"{n}.{metric}"].dropna().to_numpy())
                colours.append(palette.estimate_colour(n, names))
        fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(labels) + 2), 4.5))
        boxes = ax.boxplot(data, tick_labels=labels, showmeans=True, patch_artist=True,  # the mean not in truth's green
                           meanprops={"marker": "^", "markerfacecolor": "white", "markeredgecolor": "0.2"})
        for k, rgb in enumerate(colours):  # each estimator in its colour of the run figures and the viewer
            boxes["boxes"][k].set(facecolor=palette.unit(palette.pale(rgb)), edgecolor=palette.unit(rgb))
            boxes["medians"][k].set(color=palette.unit(rgb), linewidth=1.6)
            for part in ("whiskers", "caps"):
                for line in boxes[part][2 * k : 2 * k + 2]:
                    line.set(color=palette.unit(rgb))
        ax.set_ylabel(f"{metric} (m)")
        ax.set_title(f"{metric} per estimator" + (f" and {', '.join(groups)}" if groups else "") + f", {len(finished)} runs\n"
                     + pooled_note(finished, [c for c in (*pooled, *by) if c not in groups and c in swept(finished)]), fontsize=9)
        written.append(_save(fig, folder / f"{metric}_per_estimator.png"))
        for parameter in by:
            if not pd.api.types.is_numeric_dtype(finished[parameter]) or finished[parameter].nunique() < 2:
                continue
            fig, ax = plt.subplots(figsize=(6.5, 4.5))
            for name in names:
                band = mean_band(finished, parameter, f"{name}.{metric}")
                x = band.index.to_numpy(dtype=float)
                rgb = palette.estimate_colour(name, names)
                ax.plot(x, band["mean"], marker="o", color=palette.unit(rgb), label=name, zorder=3)
                # the band edged in its estimator's colour: overlapping bands still say whose they are
                ax.fill_between(x, band["mean"] - band["half_width"], band["mean"] + band["half_width"], facecolor=(*palette.unit(palette.pale(rgb)), 0.3),
                                edgecolor=palette.unit(rgb), linewidth=0.8, linestyle="--")
            ax.set_xlabel(parameter)
            ax.set_ylabel(f"mean {metric} (m), 95 % band")
            ax.set_title(f"{metric} against {parameter}\n" + pooled_note(finished, [c for c in swept(finished) if c != parameter]), fontsize=9)
            ax.legend()
            written.append(_save(fig, folder / f"{metric}_vs_{parameter}.png"))
    rates = success(table).groupby(table["controller"]).mean()
    fig, ax = plt.subplots(figsize=(max(6, 1.4 * len(rates) + 2), 4.5))
    ax.bar(rates.index.astype(str), 100 * rates.to_numpy(), color=palette.unit(palette.NEUTRAL))
    ax.set_ylim(0, 100)
    ax.set_ylabel("success rate (%)")
    what = "runs without error or fall" + (" that reached the goal" if table["until_goal"].astype(bool).any() else "")
    ax.set_title(f"{what}, per controller\n" + pooled_note(table, [c for c in swept(table) if c != "controller"]), fontsize=9)
    written.append(_save(fig, folder / "success_per_controller.png"))
    return written


def _save(fig, path: Path) -> Path:  # noqa: ANN001 (a matplotlib Figure)
    import matplotlib.pyplot as plt

    fig.tight_layout()
    with replacing(path) as file:  # (never through a link planted in the folder)
        fig.savefig(file, format="png", dpi=110)
    plt.close(fig)
    return path


def terminal_table(summary: pd.DataFrame, metric: str = METRIC) -> str:
    """`summary_table` for a terminal: each estimator's metric as one 'mean +- std' column, its
    NEES over the runs as 'mean in low-high' (the 95 % interval of that many runs) and the verdict."""
    per_estimator = (*(f".{metric}.{part}" for part in ("mean", "std", "n")), *(f".nees.{part}" for part in ("mean", "runs", "low", "high", "verdict")))
    shown = summary[[c for c in summary.columns if not c.endswith(per_estimator)]].copy()
    shown["success_%"] = shown["success_%"].map(lambda v: f"{v:.0f}")
    for column in [c for c in summary.columns if c.endswith(f".{metric}.mean")]:
        name = column.removesuffix(".mean")
        shown[f"{name} (m)"] = [f"{m:.4f} +- {s:.4f}" if np.isfinite(s) else f"{m:.4f}" for m, s in zip(summary[column], summary[f"{name}.std"])]
    for column in [c for c in summary.columns if c.endswith(".nees.mean")]:
        name = column.removesuffix(".nees.mean")
        shown[f"{name} NEES (95 % interval)"] = [
            "-" if not runs else f"{m:.3g} in {low:.2f}-{high:.2f} {verdict}"
            for m, runs, low, high, verdict in zip(summary[column], summary[f"{name}.nees.runs"], summary[f"{name}.nees.low"], summary[f"{name}.nees.high"], summary[f"{name}.nees.verdict"])
        ]
    return shown.to_string(index=False)
