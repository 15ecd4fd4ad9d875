"""Tolerances for numbers a source prints with a fixed number of decimals (the spec's tables, the
thesis's examples): our double-precision result agrees when it is within one unit of the printed
last place (a unit, not a half, because some tables truncate rather than round)."""

from __future__ import annotations


def places(decimals: int) -> float:
    """One unit in the last printed place of a number given with `decimals` decimals."""
    return 10.0**-decimals
