"""The figures of a sweep: error distributions per estimator, error against each swept parameter
with 95 % confidence bands, and success rate per controller (PNG, matplotlib, headless).

    ctsim sweep report runs/noise      # or: write_report("runs/noise")
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sim.experiments import store
from sim.experiments.plan import DEFAULTS

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
    ok = (table["reason"] != "error") & ~table["fell"].fillna(False).astype(bool)
    return ok & (table["reached_goal"].fillna(False).astype(bool) | ~table["until_goal"].astype(bool))


def write_report(out: str | Path, metric: str = METRIC) -> list[Path]:
    """Draw the figures of the sweep in `out` into `out/figures/`; the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    table = store.load(out)
    if table.empty:
        raise ValueError(f"{out}: no finished runs to report on")
    folder = out / "figures"
    folder.mkdir(exist_ok=True)
    written = []
    names = estimators(table, metric)
    finished = table[table["reason"] != "error"]
    if names and len(finished):
        fig, ax = plt.subplots(figsize=(1.6 * len(names) + 2, 4))
        data = [finished[f"{n}.{metric}"].dropna().to_numpy() for n in names]
        ax.boxplot(data, tick_labels=names, showmeans=True)
        ax.set_ylabel(f"{metric} (m)")
        ax.set_title(f"{metric} per estimator, {len(finished)} runs")
        written.append(_save(fig, folder / f"{metric}_per_estimator.png"))
        for parameter in swept(finished):
            if parameter == "seed" or not pd.api.types.is_numeric_dtype(finished[parameter]):
                continue
            fig, ax = plt.subplots(figsize=(6, 4))
            for name in names:
                band = mean_band(finished, parameter, f"{name}.{metric}")
                x = band.index.to_numpy(dtype=float)
                ax.plot(x, band["mean"], marker="o", label=name)
                ax.fill_between(x, band["mean"] - band["half_width"], band["mean"] + band["half_width"], alpha=0.2)
            ax.set_xlabel(parameter)
            ax.set_ylabel(f"mean {metric} (m), 95 % band")
            ax.legend()
            written.append(_save(fig, folder / f"{metric}_vs_{parameter}.png"))
    rates = success(table).groupby(table["controller"]).mean()
    fig, ax = plt.subplots(figsize=(1.4 * len(rates) + 2, 4))
    ax.bar(rates.index.astype(str), 100 * rates.to_numpy())
    ax.set_ylim(0, 100)
    ax.set_ylabel("success rate (%)")
    ax.set_title("runs without error or fall" + (" that reached the goal" if table["until_goal"].astype(bool).any() else ""))
    written.append(_save(fig, folder / "success_per_controller.png"))
    return written


def _save(fig, path: Path) -> Path:  # noqa: ANN001 (a matplotlib Figure)
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def summary(table: pd.DataFrame, metric: str = METRIC) -> pd.DataFrame:
    """Mean, standard deviation and count of `metric` per estimator (the printed table)."""
    finished = table[table["reason"] != "error"]
    rows = {n: finished[f"{n}.{metric}"].agg(["mean", "std", "count"]) for n in estimators(table, metric)}
    return pd.DataFrame(rows).T if rows else pd.DataFrame(columns=["mean", "std", "count"], dtype=np.float64)
