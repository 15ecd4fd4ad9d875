"""The scores of a results file (`sim.experiments.evaluation`): per scenario and estimator the
means over the seeds and the NEES at the runs' end against its chi-square interval, and overall a
ranking.

The ranking orders estimators by the geometric mean over the scenarios of their mean ATE: a
ratio, so that every scenario counts alike whether its errors are millimetres (exact sensors) or
decimetres (harsh noise); half the ATE in one scenario makes up for twice it in another. An
estimator that failed a run ranks after every one that failed none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from sim.analysis.nees import over_runs
from sim.experiments.evaluation import METRICS

SCALE = {"ate_rmse": ("ATE", "mm", 1e3), "rpe_translation": ("RPE", "mm", 1e3), "rpe_rotation": ("RPE rot", "°", 180.0 / math.pi),
         "final_position_error": ("final error", "mm", 1e3)}  # fmt: skip
"""The metrics scored, each with its short name, unit and factor from SI, as the tables show them."""
RANKED_BY = "ate_rmse"


def runs_frame(results: dict[str, Any]) -> pd.DataFrame:
    """One row per run and estimator: scenario, seed, estimator and its metrics; an estimator that
    failed the run has a row with `failed` set and no metrics."""
    rows = []
    for run in results["runs"]:
        for name in results_estimators(results):
            values = run["metrics"].get(name)
            failed = run.get("failed", {}).get(name) or (None if values is not None else run.get("failed", {}).get("run"))
            if values is not None or failed is not None:
                rows.append({"scenario": run["scenario"], "seed": run["seed"], "estimator": name, "failed": failed,
                             **{k: (np.nan if v is None else v) for k, v in (values or {}).items()}})  # fmt: skip
    columns = ["scenario", "seed", "estimator", "failed", *METRICS]
    return pd.DataFrame(rows).reindex(columns=columns) if rows else pd.DataFrame(columns=columns)


def scenarios(results: dict[str, Any]) -> list[str]:
    """The scenarios in the suite's order, as the runs come (a results file's keys are sorted)."""
    return list(dict.fromkeys(run["scenario"] for run in results["runs"]))


def results_estimators(results: dict[str, Any]) -> list[str]:
    """Every estimator of a results file, the shipped ones first in a run's order, then the submitted ones by name."""
    seen: dict[str, None] = {}
    for run in results["runs"]:
        seen.update(dict.fromkeys(run["metrics"]))
        seen.update(dict.fromkeys(k for k in run.get("failed", {}) if k != "run"))
    submitted = set(results["estimators"])
    return [n for n in seen if n not in submitted] + sorted(n for n in seen if n in submitted)


def per_scenario(results: dict[str, Any]) -> pd.DataFrame:
    """Per scenario and estimator: runs scored, runs failed, mean and standard deviation of each
    metric of SCALE over the seeds (SI units), and the mean NEES at the runs' end with its 95 %
    interval for that many runs and the verdict (`sim.analysis.nees.over_runs`)."""
    frame = runs_frame(results)
    rows = []
    for scenario in scenarios(results):
        for name in results_estimators(results):
            part = frame[(frame["scenario"] == scenario) & (frame["estimator"] == name)]
            scored = part[part["failed"].isna()]
            row = {"scenario": scenario, "estimator": name, "runs": len(scored), "failed": len(part) - len(scored)}
            for metric in SCALE:
                values = scored[metric].dropna() if metric in scored else pd.Series(dtype=float)
                row[f"{metric}.mean"], row[f"{metric}.std"] = (float(values.mean()), float(values.std(ddof=1))) if len(values) else (np.nan, np.nan)
            judged = over_runs(scored["nees_final"].to_numpy(dtype=float) if "nees_final" in scored else np.empty(0))
            row.update({"nees.mean": judged.mean, "nees.runs": judged.runs, "nees.low": judged.low, "nees.high": judged.high, "nees.verdict": judged.verdict})
            rows.append(row)
    return pd.DataFrame(rows)


FLOOR = 1e-9
"""The least a mean error counts for in a geometric mean (m, rad): an exact zero would make it zero."""


def _geometric_mean(values: pd.Series) -> float:
    """Geometric mean, or nan where a scenario has none (an RPE of runs under 2 m): a mean over
    some of the scenarios would not compare with another estimator's over all of them."""
    values = values.to_numpy(dtype=float)
    return float(np.exp(np.log(np.maximum(values, FLOOR)).mean())) if len(values) and np.isfinite(values).all() else np.nan


def ranking(scores: pd.DataFrame) -> pd.DataFrame:
    """One row per estimator, best first: its rank, the geometric mean over the scenarios of each
    metric's mean (SI units), in how many scenarios its NEES was consistent of those where it has
    one, and its failed runs."""
    rows = []
    for name, part in scores.groupby("estimator", sort=False):
        row = {"estimator": name, **{metric: _geometric_mean(part[f"{metric}.mean"]) for metric in SCALE}}
        judged = part[part["nees.runs"] > 0]
        row["nees_consistent"] = f"{int((judged['nees.verdict'] == 'consistent').sum())} of {len(judged)}" if len(judged) else "-"
        row["failed"] = int(part["failed"].sum())
        rows.append(row)
    table = pd.DataFrame(rows)
    table = table.assign(_failed=table["failed"] > 0, _key=table[RANKED_BY].fillna(np.inf)).sort_values(["_failed", "_key", "estimator"], kind="stable")
    table.insert(0, "rank", range(1, len(table) + 1))
    return table.drop(columns=["_failed", "_key"]).reset_index(drop=True)


FULL_BELOW = 1e9
"""Values from 10**digits up to this are printed in full (1,270 mm, not 1.27e+03); beyond it (a
merged results file may carry any finite number) in exponent form, so no cell runs to 300 digits."""


def _shown(value: float, digits: int = 3) -> str:
    """`digits` significant digits, thousands in full with their separators (`FULL_BELOW`)."""
    if not np.isfinite(value):
        return "-"
    return f"{value:,.0f}" if 10**digits <= abs(value) < FULL_BELOW else f"{value:.{digits}g}"


def ranking_text(table: pd.DataFrame) -> pd.DataFrame:
    """The ranking for people: each metric in its unit (SCALE)."""
    shown = table[["rank", "estimator"]].copy()
    for metric, (label, unit, factor) in SCALE.items():
        shown[f"{label} ({unit})"] = [_shown(v * factor) for v in table[metric]]
    return shown.assign(**{"NEES consistent": table["nees_consistent"], "failed runs": table["failed"]})


def scenario_text(scores: pd.DataFrame, metric: str = RANKED_BY) -> pd.DataFrame:
    """Scenarios down, estimators across: the mean of `metric` over the seeds in its unit."""
    label, unit, factor = SCALE[metric]
    table = scores.pivot(index="scenario", columns="estimator", values=f"{metric}.mean").reindex(index=scores["scenario"].unique(), columns=scores["estimator"].unique())
    return table.map(lambda v: _shown(v * factor)).reset_index().rename_axis(columns=None)


NEES_DASH = "'-': no covariance, or a degenerate one, where a NEES would mean nothing"
"""What a dash in a NEES table says."""


def nees_text(scores: pd.DataFrame) -> pd.DataFrame:
    """Scenarios down, estimators across: the mean NEES at the runs' end and its verdict; '-' where
    no run gave one (no covariance, or a degenerate one: `NEES_DASH`)."""
    judged = scores[scores["nees.runs"] > 0]
    cells = judged.assign(cell=[f"{_shown(m)} {'ok' if v == 'consistent' else 'over' if v == 'over-confident' else 'under'}" for m, v in zip(judged["nees.mean"], judged["nees.verdict"])])
    table = cells.pivot(index="scenario", columns="estimator", values="cell").reindex(index=scores["scenario"].unique(), columns=scores["estimator"].unique())
    return table.astype(object).fillna("-").reset_index().rename_axis(columns=None)  # (an estimator no run judged is a column of nan floats)


def terminal(results: dict[str, Any]) -> str:
    """The ranking, the ATE per scenario and the NEES verdicts, as text under their headings."""
    scores = per_scenario(results)
    runs = int(scores["nees.runs"].max()) if len(scores) else 0
    interval = f"{over_runs(np.full(runs, 3.0)).low:.2f}-{over_runs(np.full(runs, 3.0)).high:.2f} for {runs} runs" if runs else "no runs scored"
    parts = {
        f"Ranking on suite {results['suite']} v{results['suite_version']} ({len(scenarios(results))} scenarios x {len(results['seeds'])} seeds), "
        "geometric means over the scenarios of the means over the seeds": ranking_text(ranking(scores)),
        "ATE (mm) per scenario, mean over the seeds": scenario_text(scores),
        f"NEES at the runs' end, mean over the seeds (ok: in its 95 % interval, {interval}; over: over-confident; under: too cautious; {NEES_DASH})": nees_text(scores),
    }
    return "\n\n".join(f"{heading}:\n{part.to_string(index=False)}" for heading, part in parts.items())
