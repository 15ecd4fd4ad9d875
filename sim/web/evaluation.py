"""The files of `ctsim evaluate` beside its results file: `scores.csv` (per scenario and
estimator), `ranking.csv`, and `report.html`, one self-contained page with the ranking, the
tables per scenario and three figures (ATE per scenario with each seed's run, NEES at the runs'
end against its interval, the ranking's ATE).
"""

from __future__ import annotations

from html import escape
from pathlib import Path
from typing import Any

import numpy as np

from sim.analysis.run_folder import REPORT  # (the page of every folder ctsim writes: a run's, a sweep's, an evaluation's)
from sim.experiments.evaluation import failed_runs
from sim.experiments.scores import NEES_DASH, SCALE, nees_text, per_scenario, ranking, ranking_text, results_estimators, runs_frame, scenario_text
from sim.experiments.scores import scenarios as suite_order
from sim.out_files import replacing, write_text
from sim.views import palette
from sim.views.html import facts_table, frame_table, image, page


def write_tables(results: dict[str, Any], out: Path) -> list[Path]:
    """scores.csv and ranking.csv (SI units: m, rad) in `out`."""
    scores = per_scenario(results)
    written = []
    for name, frame in (("scores.csv", scores), ("ranking.csv", ranking(scores))):
        with replacing(out / name, text=True, newline="") as file:
            frame.to_csv(file, index=False)
        written.append(out / name)
    return written


def _figure(width: float, height: float) -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(figsize=(width, height))


def _plain_log(axis: Any) -> None:
    """A log axis labelled 2, 5, 10, 20 rather than 2 x 10^0."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(FuncFormatter(lambda value, _: ""))


def _png(fig: Any) -> bytes:
    import io

    import matplotlib.pyplot as plt

    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    return buffer.getvalue()


def ate_figure(results: dict[str, Any]) -> bytes:
    """Per scenario a bar per estimator, its mean ATE over the seeds, each seed's run a dot on it (log scale)."""
    frame = runs_frame(results)
    frame = frame[frame["failed"].isna()] if len(frame) else frame
    names, scenarios = results_estimators(results), suite_order(results)
    fig, ax = _figure(max(8.0, 0.22 * len(names) * len(scenarios) + 3.0), 4.8)
    width = 0.8 / max(1, len(names))
    for k, name in enumerate(names):
        colour = palette.unit(palette.estimate_colour(name, names))
        x = np.arange(len(scenarios)) + (k - (len(names) - 1) / 2) * width
        values = [frame[(frame["scenario"] == s) & (frame["estimator"] == name)]["ate_rmse"].to_numpy(dtype=float) * 1e3 for s in scenarios]
        ax.bar(x, [v.mean() if len(v) else np.nan for v in values], width * 0.92, color=palette.unit(palette.pale(palette.estimate_colour(name, names))),
               edgecolor=colour, label=name)  # fmt: skip
        for where, v in zip(x, values):
            ax.plot(np.full(len(v), where), v, "o", color=colour, markersize=3)
    ax.set_yscale("log")
    _plain_log(ax.yaxis)
    ax.set_xticks(np.arange(len(scenarios)), scenarios, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("ATE (mm), log scale")
    ax.set_title(f"ATE per scenario: bar the mean over {len(results['seeds'])} seeds, dots each seed's run", fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="estimator", title_fontsize=8)
    return _png(fig)


def nees_figure(scores: Any) -> bytes:
    """Per scenario each estimator's mean NEES at the runs' end, the grey bar its 95 % interval (log scale)."""
    judged = scores[scores["nees.runs"] > 0]
    scenarios = list(scores["scenario"].unique())
    names = list(judged["estimator"].unique())
    fig, ax = _figure(max(8.0, 0.9 * len(scenarios) + 3.0), 4.5)
    for k, scenario in enumerate(scenarios):
        part = judged[judged["scenario"] == scenario]
        if len(part):
            ax.fill_between([k - 0.4, k + 0.4], part["nees.low"].iloc[0], part["nees.high"].iloc[0], color="0.88", zorder=0)
    for j, name in enumerate(names):
        part = judged[judged["estimator"] == name].set_index("scenario").reindex(scenarios)
        x = np.arange(len(scenarios)) + (j - (len(names) - 1) / 2) * 0.6 / max(1, len(names))
        ax.plot(x, part["nees.mean"], "o", color=palette.unit(palette.estimate_colour(name, names)), label=name)
    ax.axhline(3.0, color="0.5", linewidth=0.8, linestyle="--")
    ax.set_yscale("log")
    _plain_log(ax.yaxis)
    ax.set_xticks(np.arange(len(scenarios)), scenarios, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("mean NEES at the runs' end")
    ax.set_title("NEES over the seeds; grey: its 95 % interval for a consistent estimator (3 dashed)", fontsize=10)
    if names:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="estimator", title_fontsize=8)
    return _png(fig)


def ranking_figure(table: Any) -> bytes:
    """The ranking: each estimator's geometric mean ATE over the scenarios, best on top."""
    names = list(table["estimator"])
    fig, ax = _figure(8.0, 1.2 + 0.4 * len(names))
    y = np.arange(len(names))[::-1]
    values = table["ate_rmse"].to_numpy(dtype=float) * 1e3
    ax.barh(y, values, color=[palette.unit(palette.estimate_colour(n, names)) for n in names])
    for where, value in zip(y, values):
        ax.text(value, where, f" {value:.3g} mm", va="center", fontsize=8)
    ax.set_yticks(y, [f"{r}. {n}" for r, n in zip(table["rank"], names)], fontsize=9)
    ax.set_xlabel("geometric mean over the scenarios of the mean ATE (mm), log scale")
    if np.isfinite(values).any():  # (else every run failed: no bars to scale)
        ax.set_xscale("log")
        _plain_log(ax.xaxis)
        ax.set_xlim(right=float(np.nanmax(values)) * 3)
    return _png(fig)


def write_page(results: dict[str, Any], out: Path) -> Path:
    """report.html in `out`: facts, ranking, per-scenario tables and figures, in one file."""
    scores = per_scenario(results)
    table = ranking(scores)
    submitted = results["estimators"]
    facts = {
        "suite": f"{results['suite']}, version {results['suite_version']}: {len(results['scenarios'])} scenarios x seeds {', '.join(map(str, results['seeds']))}",
        "ctsim": results["ctsim_version"],
        "estimators submitted": ", ".join(f"{n} ({v['source']}, {v['identity'][:19]})" for n, v in submitted.items()) or "none: the shipped ones alone",
        "files": "results.json (every run's metrics: merge with `ctsim evaluate --merge`), scores.csv, ranking.csv",
    }
    scenarios = [{"scenario": name, "world": s["world"], "controller": s["controller"] + "".join(f" {k}={v}" for k, v in s["params"].items()),
                  "noise": s["noise"], "duration": f"{s['duration_s']:g} s" + (" or until the goal" if s["until_goal"] else ""), "hash": s["hash"][:12]}
                 for name, s in ((name, results["scenarios"][name]) for name in suite_order(results))]  # fmt: skip
    import pandas as pd

    body = [
        "<h2>Ranking</h2>",
        "<p>By the geometric mean over the scenarios of each estimator's mean ATE over the seeds (an estimator that failed a run ranks last); "
        "RPE as evo's <code>evo_rpe -d 1 -u m</code>; final error: position at the runs' end; NEES at the runs' end, consistent where the mean over the seeds "
        "lies in its 95 % chi-square interval.</p>",
        frame_table(ranking_text(table), 2),
        image(ranking_figure(table), "ranking"),
    ]
    failed = failed_runs(results)
    if failed:
        body += [f"<h2>Failed runs ({len({(row['scenario'], row['seed']) for row in failed})} of {len(results['runs'])})</h2>",
                 "<p>A run stops where an estimator's code raised, left, overran the step time limit or gave a pose or covariance that is no "
                 "estimate; none of the run's estimators is scored in it.</p>", frame_table(pd.DataFrame(failed), 5)]  # fmt: skip
    body += [
        "<h2>Per scenario</h2>",
        image(ate_figure(results), "ATE per scenario"),
    ]
    for metric, (label, unit, _) in SCALE.items():
        body += [f"<h3>{escape(label)} ({escape(unit)}), mean over the seeds</h3>", frame_table(scenario_text(scores, metric), 1)]
    body += [f"<h3>NEES at the runs' end (ok: consistent, over: over-confident, under: too cautious; {escape(NEES_DASH)})</h3>", frame_table(nees_text(scores), 1),
             image(nees_figure(scores), "NEES per scenario"), "<h2>Scenarios</h2>", frame_table(pd.DataFrame(scenarios), 5), "<h2>Facts</h2>", facts_table(facts)]  # fmt: skip
    return write_text(out / REPORT, page(f"ctsim evaluate: suite {results['suite']} v{results['suite_version']}", "\n".join(body)))


def write_all(results: dict[str, Any], out: Path) -> list[Path]:
    """The tables and the page of a results file, in `out`."""
    return [*write_tables(results, out), write_page(results, out)]
