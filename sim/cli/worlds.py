"""`ctsim worlds`: the shipped worlds, one line each."""

from __future__ import annotations

import argparse
import re


def first_sentence(text: str) -> str:
    """The first sentence of a text: up to a full stop followed by a capital (so that "e.g. a"
    and "0.24 m" do not end it), whitespace folded."""
    return re.split(r"(?<=[.!?])\s+(?=[A-Z])", " ".join(text.split()), maxsplit=1)[0]


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `worlds` command's options."""
    worlds = commands.add_parser("worlds", help="list the shipped worlds", description="List the shipped worlds: name, size and description.")
    worlds.set_defaults(handler=cmd_worlds)


def cmd_worlds(args: argparse.Namespace) -> int:
    import textwrap

    from sim.world.files import load_world, shipped_worlds

    for name, path in shipped_worlds().items():
        world = load_world(path)
        xmin, ymin, xmax, ymax = world.bounds
        first = first_sentence(world.description).rstrip(".")  # it says what the world is for
        room = len(world.start_order())
        lead = f"{name:<14}{xmax - xmin:5.2f} x {ymax - ymin:<5.2f} m  "
        print(textwrap.fill(f"{first} ({room} start{'s' if room != 1 else ''})", width=100, initial_indent=lead, subsequent_indent=" " * len(lead)))
    return 0
