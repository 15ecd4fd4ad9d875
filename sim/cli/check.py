"""`ctsim check`: a world file loaded and its problems or a summary reported."""

from __future__ import annotations

import argparse

from sim import sanitize


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `check` command's options."""
    check = commands.add_parser("check", help="validate a world file", description="Load a world file and report problems (file:line: problem) or OK with a summary.")
    check.add_argument("world", metavar="WORLD")
    check.set_defaults(handler=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    from sim.world.files import load_world, room_warning, world_warnings

    world = load_world(args.world)
    warnings = [w for w in (*world_warnings(world), room_warning(world)) if w]
    xmin, ymin, xmax, ymax = world.bounds
    counts = ", ".join(f"{len(getattr(world, k))} {k}" for k in ("walls", "floor", "lines", "holes", "lights", "starts", "goals", "movables"))
    for warning in warnings:
        print(f"{args.world}: warning: {warning}")
    room = len(world.start_order())
    print(f"OK {args.world}: {sanitize.name(world.name)}, {xmax - xmin:.2f} x {ymax - ymin:.2f} m; {counts}; room for {room} robot(s)")
    return 0
