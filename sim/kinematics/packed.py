"""A packed table declared once: its fields (name, width, unit, kind) in order, as a numpy
structured dtype.

Compiled code is fastest with its values packed into a few arrays, and hardest to read where
those arrays are indexed by numbers. A `Table` gives each column a name, a width, a unit and a
kind (ints stay ints, flags bools); compiled code reads a row's fields by name (`rows[i].mass`),
Python fills them by name (`rows["mass"] = ...`). The world's tables (`sim.world.layout`) and
the odometry's (`bots.odometry.layout`) are declared with it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Field(NamedTuple):
    """One field of a table: its name, how many values a row holds (1: a scalar), their unit and
    kind (a numpy scalar type, or another table's dtype for a nested record)."""

    name: str
    width: int
    unit: str
    kind: type | np.dtype = np.float64


class Table:
    """A table's declaration: its fields in order, as a numpy structured dtype."""

    def __init__(self, what: str, *fields: Field):
        self.what = what
        self.fields = fields
        self.dtype = np.dtype([(f.name, f.kind) if f.width == 1 else (f.name, f.kind, (f.width,)) for f in fields], align=True)

    def new(self, rows: int) -> np.ndarray:
        """A table of `rows` rows, every field zero (False)."""
        return np.zeros(rows, self.dtype)

    def columns(self, table: np.ndarray) -> dict[str, np.ndarray]:
        """Each field of `table` as an array of its own (views: writing them writes the table)."""
        return {f.name: table[f.name] for f in self.fields}
