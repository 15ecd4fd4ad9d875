"""The README's pictures show what the code draws now: each viewer picture's run, recorded anew
(one simulated second: entities and views do not depend on the length), logs the same entities
and lays out the same views as when `python docs/screenshots.py` made the picture."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from sim.cli.entry import main

DOCS = Path(__file__).resolve().parent.parent / "docs"


def _screenshots():
    spec = importlib.util.spec_from_file_location("screenshots", DOCS / "screenshots.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SCREENSHOTS = _screenshots()
MANIFEST = json.loads(SCREENSHOTS.MANIFEST.read_text())


@pytest.mark.parametrize("picture", sorted(SCREENSHOTS.RUNS))
def test_a_viewer_picture_shows_what_the_code_draws_now(picture, tmp_path):
    arguments, _ = SCREENSHOTS.RUNS[picture]
    made = MANIFEST.get(picture)
    assert made is not None and made["arguments"] == arguments, f"docs/{picture}.png is not made from RUNS: run python docs/screenshots.py"
    short = list(arguments)
    short[short.index("--duration") + 1] = "1"
    assert main(["run", *short, "--out", str(tmp_path / "o"), "--no-report"]) == 0
    now = SCREENSHOTS.drawn(tmp_path / "o" / "run.rrd")
    assert now["views"] == made["views"], f"the viewer's layout changed since docs/{picture}.png: run python docs/screenshots.py"
    assert now["entities"] == made["entities"], f"what the recording draws changed since docs/{picture}.png: run python docs/screenshots.py"
