"""Self-contained HTML pages: `report.html` of a run folder and of a sweep folder, each one file
with its figures inside (PNG data URIs), to mail, attach to a submission or open from a share.

A run's page links to its recording twice: the file itself (for the native viewer) and the
address `ctsim view RUN_DIR` serves it at (a page cannot start a command: it says which one).
"""

from __future__ import annotations

from html import escape
from pathlib import Path

from sim.analysis.run_folder import REPORT, RunFolder, read_summary
from sim.out_files import write_text
from sim.views.html import facts_table, frame_table, image, page, run_facts, summary_table
from sim.web.serve import DEFAULT_HOST, DEFAULT_PORT, addresses


def write_run_report(run_dir: str | Path) -> Path:
    """report.html in a run folder written by `ctsim run` (its summary.json, PNGs and run.rrd)."""
    run_dir = Path(run_dir)
    summary = read_summary(run_dir)
    pictures = [path for path in RunFolder(run_dir).figures if _own_file(path)]  # (first and in this order; any other PNG follows)
    pictures += sorted(p for p in run_dir.glob("*.png") if p not in pictures and _own_file(p))
    body = [
        "<h2>Summary</h2>",
        summary_table(summary["robots"]),
        "<h2>Recording</h2>",
        _recording_links(run_dir),
        "<h2>Figures</h2>" if pictures else "<p>No figures (the run was written with <code>--no-report</code>: <code>ctsim report</code> draws them).</p>",
        *(image(p, p.stem) for p in pictures),
        "<h2>Run facts</h2>",
        facts_table(run_facts(summary)),
    ]
    title = f"ctsim run: {summary['world']['name']}, {', '.join(sorted({r['controller'] for r in summary['robots']}))}, seed {summary['seed']}"
    return write_text(RunFolder(run_dir).report, page(title, "\n".join(body)))


def _own_file(path: Path) -> bool:
    """A regular file in the folder itself, not a link (whose target a page must not carry away)."""
    return not path.is_symlink() and path.is_file()


def _recording_links(run_dir: Path) -> str:
    recording = RunFolder(run_dir).recording
    if not recording.is_file():
        return "<p>No recording in this folder.</p>"
    command = f"ctsim view {run_dir}"
    return (
        f"<p>In a browser: run <code>{escape(command)}</code>, then "
        f"<a href='{escape(addresses(DEFAULT_HOST, DEFAULT_PORT, DEFAULT_PORT + 1)[0], quote=True)}'>open the recording in rerun's web viewer</a> "
        f"(the address <code>ctsim view</code> prints). With rerun installed: <code>rerun {escape(str(recording))}</code> "
        f"(<a href='run.rrd'>run.rrd</a>).</p>"
    )


def write_sweep_report(sweep_dir: str | Path, by: list[str] | None = None) -> list[Path]:
    """The summary and figures of a sweep folder grouped `by` settings (`sim.experiments.report`)
    and its report.html: how the runs ended and each estimator's error per group (tables that
    fit the page, numbers to their precision), the figures, the sweep's facts. The files
    written, the page last."""
    from sim.experiments import store
    from sim.experiments.report import OUTCOMES, grouping, outcomes, pooled_note, shown_tables, summary_table, write_report

    sweep_dir = Path(sweep_dir)
    written = write_report(sweep_dir, by=by)
    figures = [p for p in written if p.suffix == ".png"]
    table = store.load(sweep_dir)
    by, pooled = grouping(table, by)
    ended = outcomes(table).value_counts()
    facts = {
        "runs": len(table),
        "ended": ", ".join(f"{ended[kind]} {kind}" for kind in OUTCOMES if kind in ended),
        "table": "results.parquet (every run), summary.csv (these tables' numbers in full)",
    }
    body = [f"<h2>Per {escape(', '.join(by) or 'sweep')}</h2>", f"<p>{escape(pooled_note(table, pooled))}</p>"]
    for heading, part in shown_tables(summary_table(table, by)).items():
        body += [f"<h3>{escape(heading)}</h3>", frame_table(part, text_columns=max(1, len(by)))]
    body += [*(image(p, p.stem) for p in figures), "<h2>Sweep</h2>", facts_table(facts)]
    return [*written, write_text(sweep_dir / REPORT, page(f"ctsim sweep: {sweep_dir.resolve().name}", "\n".join(body)))]
