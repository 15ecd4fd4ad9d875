"""`ctsim lab`: lab exercises with automatic checking (the handler is `sim.lab.cli`)."""

from __future__ import annotations

import argparse


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    from sim.lab.arguments import add_parser as add_lab_parser

    add_lab_parser(commands, cmd_lab)


def cmd_lab(args: argparse.Namespace) -> int:
    from sim.lab.cli import lab_command

    return lab_command(args)
