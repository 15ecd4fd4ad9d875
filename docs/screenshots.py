"""Make the README's pictures from fresh runs: the rerun viewer on the maze, the line course and
three robots; the two PNG figures of the maze run; the README's contest (its bracket, its final in
the viewer); the pygame window (SDL offscreen).

    .venv/bin/python docs/screenshots.py [--shot ../shared/tools/rerun-shot]

The viewer screenshots need `rerun-shot` (the real rerun viewer on a virtual display); without it
they are skipped, saying so, and the rest is still made.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
RUNS = {
    "viewer_maze": (["maze", "--duration", "60"], 59),
    "viewer_line": (["line", "--controller", "follow_line", "--duration", "40"], 39),
    "viewer_three_robots": (["maze", "--robots", "3", "--duration", "30"], 29),
}
"""Picture name -> (ctsim run arguments, simulated second to show)."""
CONTEST = ["contest", "right=solve_maze", "left=solve_maze,hand=left", "fast=solve_maze,speed_m_s=0.25",
           "fastleft=solve_maze,hand=left,speed_m_s=0.25", "slow=solve_maze,speed_m_s=0.1", "wanderer=wander",
           "careful=avoid_holes,inner=wander", "fw=firmware:tests/fake_firmware.py,rc5=1:3", "--time-limit", "120"]  # fmt: skip
"""The README's contest: its bracket, and its final in the viewer when the winner arrives."""


def _contest(folder: Path, shot: str, python: str) -> None:
    import sqlite3

    out = folder / "contest"
    subprocess.run([python, "-m", "sim.cli", "contest", *CONTEST, "--out", str(out)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    shutil.copy(out / "bracket.png", DOCS / "contest_bracket.png")
    with sqlite3.connect(out / "contest.sqlite") as db:
        recording, decided = db.execute("SELECT recording, time FROM games WHERE level = 1").fetchone()
    if Path(shot).is_file():
        second = round(decided - 0.5, 1)  # just before the winner's arrival: both bots still on the map
        subprocess.run([shot, str(out / recording), str(folder / "final"), str(second), python], cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        shutil.copy(f"{folder / 'final'}_t{second:g}.png", DOCS / "viewer_contest.png")


def _window(path: Path) -> None:
    """Drive the c't-Bot up the maze's first corridor and save the window's last frame."""
    import pygame

    from bots.ctbot import CTBOT
    from sim.views.window import play
    from sim.world.files import load_world

    press = lambda key: pygame.event.Event(pygame.KEYDOWN, key=key)  # noqa: E731
    release = lambda key: pygame.event.Event(pygame.KEYUP, key=key)  # noqa: E731
    events = {5: [press(pygame.K_UP)], 140: [release(pygame.K_UP), press(pygame.K_RIGHT)], 170: [release(pygame.K_RIGHT), press(pygame.K_UP)], 260: [release(pygame.K_UP)]}
    with tempfile.TemporaryDirectory() as folder:
        play(load_world("maze"), CTBOT, Path(folder) / "play.rrd", frames=300, fps=1000, speed=10, events=events, snapshot=path)


MANIFEST = DOCS / "screenshots.json"
"""What each viewer picture shows: its run's arguments, the recording's entities and the viewer's
views (name, origin). `tests/test_docs.py` records the same runs anew and compares: a change to
what the code draws fails there until the pictures are made again."""


def drawn(recording: Path) -> dict[str, list]:
    """The entity paths a recording logs, and the (name, origin) of each view of its blueprint."""
    import rerun.chunk

    reader = rerun.chunk.RrdReader(str(recording))
    entities = sorted({chunk.entity_path for chunk in reader.stream().to_chunks()})
    (store,) = reader.blueprints()
    names, origins = {}, {}
    for chunk in reader.stream(store=store).to_chunks():
        batch, where = chunk.to_record_batch(), chunk.entity_path
        if "ViewBlueprint:space_origin" in batch.schema.names:
            origins[where] = batch.column("ViewBlueprint:space_origin").to_pylist()[-1][0]
        if "ViewBlueprint:display_name" in batch.schema.names:
            names[where] = batch.column("ViewBlueprint:display_name").to_pylist()[-1][0]
    return {"entities": entities, "views": sorted([names.get(view, ""), origin] for view, origin in origins.items())}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shot", default=str(ROOT.parent / "shared" / "tools" / "rerun-shot"), help="the rerun-shot tool")
    args = parser.parse_args()
    python = sys.executable
    manifest = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, (arguments, second) in RUNS.items():
            out = Path(folder) / name
            subprocess.run([python, "-m", "sim.cli", "run", *arguments, "--out", str(out)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
            manifest[name] = {"arguments": arguments, **drawn(out / "run.rrd")}
            if name == "viewer_maze":
                for figure in ("trajectories.png", "errors.png"):
                    shutil.copy(out / figure, DOCS / f"figure_{figure}")
            if Path(args.shot).is_file():
                prefix = Path(folder) / name
                subprocess.run([args.shot, str(out / "run.rrd"), str(prefix), str(second), python], cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                shutil.copy(f"{prefix}_t{second:g}.png", DOCS / f"{name}.png")
            else:
                print(f"screenshots: no rerun-shot at {args.shot}: viewer picture {name}.png not made", file=sys.stderr)
        _contest(Path(folder), args.shot, python)
    _window(DOCS / "window.png")
    MANIFEST.write_text(json.dumps(manifest, indent=1) + "\n")
    print("\n".join(str(p.relative_to(ROOT)) for p in sorted(DOCS.glob("*.png"))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
