"""A run as HTML: the summary table, the run's facts and its PNG figures embedded, in one string
with no file beside it. `report.html` of a run folder (`sim.web.report`) and a result's view in
Jupyter (`Result._repr_html_`) are both made of these parts.

A robot is described as in summary.json: name, controller, distance (m), collisions, fell,
goal_time (s or None) and estimates (estimate -> final_position_error, ate_rmse (m),
final_heading_error (rad)).
"""

from __future__ import annotations

import base64
import math
from html import escape
from pathlib import Path
from typing import Any

from sim.analysis.summary import goal_note
from sim.views import palette

STYLE = """
table.ctsim { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.92em; }
table.ctsim th, table.ctsim td { padding: 0.25em 0.8em; border-bottom: 1px solid #ddd; text-align: right; }
table.ctsim th:first-child, table.ctsim td:first-child, table.ctsim td.text { text-align: left; }
table.ctsim tr.robot td { border-top: 2px solid #999; font-weight: 600; }
img.ctsim { max-width: 100%; display: block; margin: 0.5em 0 1.5em; }
div.wide { overflow-x: auto; max-width: 100%; }
table.nowrap { font-size: 0.85em; }
table.nowrap td, table.nowrap th { white-space: nowrap; padding: 0.25em 0.55em; }
table.ctsim th.text { text-align: left; }
code { background: #f2f2f2; padding: 0.1em 0.3em; border-radius: 3px; }
.swatch { display: inline-block; width: 0.8em; height: 0.8em; border-radius: 2px; margin-right: 0.35em; }
"""
"""Styles of every page and fragment: `table.ctsim` and `img.ctsim` keep them off a notebook's own."""
PAGE_STYLE = "body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1200px; color: #222; padding: 0 1em; }"


def summary_table(robots: list[dict[str, Any]]) -> str:
    """Per robot its distance, collisions and how it ended; per estimate its errors: the table
    `ctsim run` prints, as HTML."""
    head = ("robot / estimate", "distance m", "collisions", "final err m", "ATE RMS m", "final hdg °", "")
    rows = ["<tr>" + "".join(f"<th>{escape(h)}</th>" for h in head) + "</tr>"]
    for robot in robots:
        notes = ["fell into a hole" if robot["fell"] else "", goal_note(robot)]
        rows.append(
            f"<tr class='robot'><td>{escape(robot['name'])} <span style='font-weight:normal'>({escape(robot['controller'])})</span></td>"
            f"<td>{robot['distance']:.3f}</td><td>{robot['collisions']}</td><td></td><td></td><td></td>"
            f"<td class='text'>{escape(', '.join(n for n in notes if n))}</td></tr>"
        )
        for name, errors in robot["estimates"].items():
            swatch = "#{:02x}{:02x}{:02x}".format(*palette.estimate_colour(name, list(robot["estimates"])))
            rows.append(
                f"<tr><td>&nbsp;&nbsp;<span class='swatch' style='background:{swatch}'></span>{escape(name)}</td><td></td><td></td>"
                f"<td>{_number(errors.get('final_position_error'), 4)}</td><td>{_number(errors.get('ate_rmse'), 4)}</td>"
                f"<td>{_number(errors.get('final_heading_error'), 2, math.degrees)}</td><td></td></tr>"
            )
    return "<table class='ctsim'>" + "".join(rows) + "</table>"


def _number(value: float | None, digits: int, convert=lambda v: v) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{convert(value):.{digits}f}"


def run_facts(summary: dict[str, Any]) -> dict[str, str]:
    """What ran and how it ended, from a summary.json (or a dict of its shape)."""
    robots = summary["robots"]
    controllers = sorted({f"{r['controller']}" + (f" ({', '.join(f'{k}={v}' for k, v in r['params'].items())})" if r.get("params") else "") for r in robots})
    facts = {
        "world": f"{summary['world']['name']} ({summary['world'].get('source', '')})",
        "robots": ", ".join(f"{r['name']} ({r.get('robot', '')})" for r in robots),
        "controller": "; ".join(controllers),
        "noise": summary.get("noise", "none"),
        "seed": summary["seed"],
        "dt": f"{1000 * summary['dt']:g} ms",
        "simulated": f"{summary['time']:.2f} s" + (f" of {summary['duration']:g} s asked" if "duration" in summary else ""),
        "ended": summary["reason"] + (f": {summary['error']}" if summary.get("error") else ""),
    }
    if "ctsim_version" in summary:
        facts["ctsim"] = summary["ctsim_version"]
    return facts


def frame_table(frame: Any, text_columns: int = 0) -> str:
    """A DataFrame of text as a table, its first `text_columns` columns (names, settings) flush
    left like words, the rest flush right like numbers; cells never wrap (a wide table scrolls)."""
    head = "".join(f"<th class='text'>{escape(str(c))}</th>" if k < text_columns else f"<th>{escape(str(c))}</th>" for k, c in enumerate(frame.columns))
    rows = ["<tr>" + "".join(f"<td class='text'>{escape(str(v))}</td>" if k < text_columns else f"<td>{escape(str(v))}</td>" for k, v in enumerate(values)) + "</tr>"
            for values in frame.itertuples(index=False)]  # fmt: skip
    return f"<div class='wide'><table class='ctsim nowrap'><tr>{head}</tr>{''.join(rows)}</table></div>"


def facts_table(facts: dict[str, Any]) -> str:
    """Key-value rows: what ran, and how it ended."""
    rows = "".join(f"<tr><td>{escape(str(k))}</td><td class='text'>{escape(str(v))}</td></tr>" for k, v in facts.items())
    return f"<table class='ctsim'>{rows}</table>"


def image(png: bytes | Path, alt: str) -> str:
    """A PNG inside the page (a data URI): the page needs no file beside it."""
    data = png.read_bytes() if isinstance(png, Path) else png
    return f"<img class='ctsim' alt='{escape(alt, quote=True)}' src='data:image/png;base64,{base64.b64encode(data).decode()}'>"


def page(title: str, body: str) -> str:
    """A whole HTML document around `body`."""
    return (f"<!doctype html>\n<html lang='en'><head><meta charset='utf-8'><title>{escape(title)}</title>"
            f"<style>{PAGE_STYLE}{STYLE}</style></head>\n<body>\n<h1>{escape(title)}</h1>\n{body}\n</body></html>\n")


def fragment(body: str) -> str:
    """`body` with the styles, for a notebook cell's output."""
    return f"<div><style>{STYLE}</style>{body}</div>"


def run_fragment(world: Any, summary: dict[str, Any], tracks: dict[str, dict[str, Any]]) -> str:
    """A run for a notebook cell: the summary table, the PNG figures (drawn here, as `ctsim run`
    draws them) and the facts. `world` a WorldSpec; `tracks` as `figures.write_figures` takes them."""
    import tempfile

    from sim.views.figures import ate_of, describe, puts_of, write_figures

    pictures = []
    if all(len(track[0]) > 1 for robot in tracks.values() for track in robot.values()):
        with tempfile.TemporaryDirectory() as folder:
            pictures = [image(path, path.stem) for path in write_figures(world, tracks, folder, subtitle=describe(summary), ate=ate_of(summary), puts=puts_of(summary))]
    return fragment(summary_table(summary["robots"]) + "".join(pictures) + facts_table(run_facts(summary)))
