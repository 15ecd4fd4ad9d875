"""`ctsim controllers`: the registered controllers and their parameters."""

from __future__ import annotations

import argparse


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `controllers` command's options."""
    controllers = commands.add_parser("controllers", help="list the registered controllers and their parameters",
                                      description="List the controllers `--controller` accepts by name, with their parameters.")
    controllers.set_defaults(handler=cmd_controllers)


def cmd_controllers(args: argparse.Namespace) -> int:
    import inspect
    import textwrap

    import bots.behaviours  # noqa: F401  (registers the shipped controllers)
    from bots.controller import REGISTRY, parameters


    if not REGISTRY:
        print("no controllers registered")
    for name in sorted(REGISTRY):
        factory = REGISTRY[name]
        shown = [p.name if p.default is inspect.Parameter.empty else f"{p.name}={p.default!r}" for p in parameters(factory).values()]
        doc = " ".join((inspect.getdoc(factory) or "").split("\n\n")[0].split())
        print(textwrap.fill(doc, width=100, initial_indent=f"{name:<16}", subsequent_indent=" " * 16))
        if shown:
            print(f"{'':<16}parameters: {', '.join(shown)}")
    return 0
