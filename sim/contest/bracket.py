"""The bracket of a contest, as people look at it: a PNG figure (matplotlib) and a self-contained
HTML page (inline style, no scripts) with every game's entries, winner, time and a link to its
recording, the preliminary round and the ranking. Both draw from the database, so they show a
contest half-way as well as a finished one.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path

from sim.contest.rules import FINAL, PRELIM, THIRD_PLACE, level_name, lowest_level
from sim.contest.store import GameRow, Store
from sim.out_files import replacing, write_text
from sim.views import palette


@dataclass(frozen=True)
class Card:
    """One game as drawn: its title, both places (seed, name, won, start slot 1 or 2), how it was
    decided and the path of its recording (relative to the contest folder)."""

    game: GameRow
    title: str
    rows: tuple[tuple[int | None, str, bool, int | None], ...]
    caption: str
    recording: str | None


def cards(store: Store) -> list[Card]:
    """The knockout games, first round first, the final and the game for third place last."""
    entries, seeds = store.entries(), store.seeds()
    out = []
    for game in store.games("level >= 0"):
        slot = {}  # the better seed starts from slot 1 (red), the other from slot 2 (blue)
        known = [e for e in (game.entry1, game.entry2) if e is not None]
        for k, entry in enumerate(sorted(known, key=lambda e: seeds.get(e, 0)), 1):
            slot[entry] = k
        rows = tuple(
            (seeds.get(e), entries[e - 1].name, game.winner == e, slot.get(e)) if e is not None else (None, "?", False, None)
            for e in (game.entry1, game.entry2)
        )  # fmt: skip
        out.append(Card(game, f"{level_name(game.level)} {game.number}" if game.level > FINAL else level_name(game.level), rows, _caption(game), game.recording))
    return out


def _caption(game: GameRow) -> str:
    if game.state != "done":
        return "to be played"
    if game.reason == "time limit":
        return f"time limit {game.time:g} s, by path"
    return f"{game.reason} {game.time:.2f} s"


def _colour(slot: int | None) -> str:
    return palette.hex_colour(palette.CONTESTANTS[slot - 1]) if slot else "#888888"


SLOT_IN = 1.15
"""Height (in) of a first-round game's place in the figure: a box and its title."""


def write_png(store: Store, path: Path) -> Path:
    """The tree from the first round (left) to the final (right), the game for third place under
    the final; each game a box with both entries (seed, name; the winner bold, a red or blue mark
    for its start slot), how and when it was decided."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    drawn = cards(store)
    entries = len(store.entries())
    low = lowest_level(entries) if entries > 1 else 1
    rounds = [low >> k for k in range(low.bit_length())]  # levels left to right: ..., 4, 2, 1
    col = {level: i for i, level in enumerate(rounds)}
    width, height = 2.9, 0.78  # a box (in)
    rows = max(low, 2)
    fig = plt.figure(figsize=(len(rounds) * (width + 0.6) + 0.4, rows * SLOT_IN + 1.3), dpi=120)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(-0.3, len(rounds) * (width + 0.6) + 0.1)
    ax.set_ylim(-(rows * SLOT_IN) - 0.9, 0.9)
    ax.axis("off")

    def centre(level: int, number: int) -> tuple[float, float]:
        if level == THIRD_PLACE:
            x, y = centre(FINAL, 1)
            return x, y - 1.9 * height
        span = low // level  # first-round places under this game
        return col[level] * (width + 0.6), -((number - 0.5) * span * SLOT_IN * rows / low)

    for card in drawn:
        x, y = centre(card.game.level, card.game.number)
        if card.game.level > FINAL:
            px, py = centre(card.game.level // 2, (card.game.number + 1) // 2)
            ax.plot([x + width, x + width + 0.3, x + width + 0.3, px], [y, y, py, py], color="0.6", linewidth=1.0, zorder=1)
        ax.add_patch(FancyBboxPatch((x, y - height / 2), width, height, boxstyle="round,pad=0.02,rounding_size=0.06", facecolor="white", edgecolor="0.45", linewidth=1.0, zorder=2))
        ax.text(x + 0.05, y + height / 2 + 0.04, card.title, fontsize=7, color="0.35", va="bottom")
        for k, (seed, name, won, slot) in enumerate(card.rows):
            ty = y + height / 4 - k * height / 2 + 0.02
            ax.plot([x + 0.1], [ty], marker="s", markersize=6, color=_colour(slot), zorder=3)
            label = f"({seed}) {name}" if seed is not None else name
            ax.text(x + 0.22, ty, label, fontsize=8.5, va="center", fontweight="bold" if won else "normal", zorder=3)
        ax.text(x + width - 0.05, y - height / 2 + 0.05, card.caption, fontsize=6.5, color="0.35", ha="right", va="bottom", zorder=3)
    settings = store.settings()
    ax.text(-0.2, 0.75, f"contest: {Path(settings['world']).stem}, {entries} entries, time limit {float(settings['time_limit']):g} s, seed {settings['seed']}",
            fontsize=10, va="top", fontweight="bold")  # fmt: skip
    ax.text(-0.2, 0.42, "(seed) name; bold: winner; red/blue: start slot 1/2; time: when the game was decided", fontsize=7.5, color="0.35", va="top")
    with replacing(path) as file:
        fig.savefig(file, format="png")
    plt.close(fig)
    return path


PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }}
h1 {{ font-size: 1.4em; margin: 0 0 .2em; }} h2 {{ font-size: 1.1em; margin: 1.6em 0 .5em; }}
.facts {{ color: #555; }}
.bracket {{ display: flex; gap: 2.2em; align-items: stretch; }}
.column {{ display: flex; flex-direction: column; }}
.column h3 {{ font-size: .85em; color: #666; margin: 0 0 .4em; }}
.round {{ display: flex; flex-direction: column; justify-content: space-around; gap: .8em; min-width: 15em; flex: 1; }}
.game {{ border: 1px solid #999; border-radius: 6px; padding: .35em .55em; background: #fff; }}
.game .who {{ display: flex; gap: .45em; align-items: center; }}
.game .who.won {{ font-weight: bold; }}
.mark {{ width: .7em; height: .7em; border-radius: 2px; display: inline-block; }}
.game .how {{ font-size: .8em; color: #555; margin-top: .2em; }}
table {{ border-collapse: collapse; }} td, th {{ padding: .2em .7em; border-bottom: 1px solid #ddd; text-align: left; }}
</style></head><body>
<h1>{title}</h1>
<p class="facts">{facts}</p>
<h2>Knockout</h2>
<div class="bracket">{rounds}</div>
<h2>Ranking</h2>
{ranking}
<h2>Preliminary round</h2>
{prelim}
<p class="facts">Open a recording with <code>rerun FILE.rrd</code>. Red and blue mark the start slots 1 and 2; the better seed starts
from slot 1. A game without an arrival is decided at the time limit by the way left to each bot's goal along the free floor (path distance).</p>
</body></html>
"""


def write_html(store: Store, path: Path, ranking_rows: list[dict]) -> Path:
    """The page: the bracket (a column per round, the game for third place beside the final), the
    ranking and the preliminary round, each game linked to its recording."""
    drawn = cards(store)
    columns = []
    for level in sorted({c.game.level for c in drawn if c.game.level != THIRD_PLACE}, reverse=True):
        games = [c for c in drawn if c.game.level == level or (level == FINAL and c.game.level == THIRD_PLACE)]
        columns.append(f'<div class="column"><h3>{html.escape(level_name(level))}</h3><div class="round">{"".join(_game_html(c) for c in games)}</div></div>')
    settings = store.settings()
    facts = (f"world {settings['world']} (preliminary: {settings['prelim_world']}), time limit {float(settings['time_limit']):g} s, "
             f"seed {settings['seed']}, step {float(settings['dt']) * 1000:g} ms, ctsim {settings['ctsim']}")
    page = PAGE.format(title=html.escape(f"Contest: {Path(settings['world']).stem}"), facts=html.escape(facts), rounds="".join(columns),
                       ranking=_table(ranking_rows), prelim=_prelim(store))  # fmt: skip
    return write_text(path, page)


def _game_html(card: Card) -> str:
    rows = "".join(
        f'<div class="who{" won" if won else ""}"><span class="mark" style="background:{_colour(slot)}"></span>'
        f'{"" if seed is None else f"({seed}) "}{html.escape(name)}</div>'
        for seed, name, won, slot in card.rows
    )  # fmt: skip
    link = f' &middot; <a href="{html.escape(card.recording)}">recording</a>' if card.recording else ""
    title = html.escape(card.game.verdict or "", quote=True)
    return f'<div class="game" title="{title}"><div class="how">{html.escape(card.title)}</div>{rows}<div class="how">{html.escape(card.caption)}{link}</div></div>'


def _table(rows: list[dict]) -> str:
    if not rows:
        return "<p>not over yet</p>"
    head = "".join(f"<th>{html.escape(str(k))}</th>" for k in rows[0])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in row.values()) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _prelim(store: Store) -> str:
    entries, seeds = store.entries(), store.seeds()
    rows = []
    for game in sorted(store.games("level = ?", PRELIM), key=lambda g: seeds.get(g.entry1, 0)):
        link = f'<a href="{html.escape(game.recording)}">recording</a>' if game.recording else ""
        cells = (seeds.get(game.entry1, ""), html.escape(entries[game.entry1 - 1].name), html.escape(game.verdict or "to be played"), link)
        rows.append("<tr>" + "".join(f"<td>{cell}</td>" for cell in cells) + "</tr>")
    return f"<table><tr><th>seed</th><th>entry</th><th>result</th><th></th></tr>{''.join(rows)}</table>"
