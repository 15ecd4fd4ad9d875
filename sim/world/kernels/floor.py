"""Compiled lookups in the floor raster (`sim.world.floor.FloorMap`): the one test of a point over
a hole (`in_hole`, also behind `FloorMap.hole_at` and a chassis's second mouse), the absorption
at a point, and c't-Sim's ground-contact rule (`hold_at_holes`)."""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def raster_cell(x: float, y: float, origin: np.ndarray, cell: float) -> tuple[int, int]:
    """The raster's column and row of the point (x, y) (m), unclamped: off the map beyond its shape."""
    return int(math.floor((x - origin[0]) / cell)), int(math.floor((y - origin[1]) / cell))


@numba.njit(cache=True)
def in_hole(x: float, y: float, hole: np.ndarray, origin: np.ndarray, cell: float, outside_is_hole: bool) -> bool:
    """Whether the point (x, y) (m) is over a hole of the raster `hole` (off the map:
    `outside_is_hole`): the one hole test of the world, its kernels and its Python code alike."""
    ix, iy = raster_cell(x, y, origin, cell)
    if ix < 0 or iy < 0 or iy >= hole.shape[0] or ix >= hole.shape[1]:
        return outside_is_hole
    return hole[iy, ix]


@numba.njit(cache=True)
def hold_at_holes(
    pose: np.ndarray,
    move: np.ndarray,
    alpha: np.ndarray,
    contacts: np.ndarray,
    anchored: np.ndarray,
    hole: np.ndarray,
    origin: np.ndarray,
    cell: float,
    outside_is_hole: bool,
    over_hole: np.ndarray,
) -> bool:
    """c't-Sim's ground-contact rule (`MasterSimulator`, "Bodenkontakt"): a robot whose planned
    move (n, 2) and turn (n,) would bring a ground contact over a hole neither moves nor turns
    this step (both zeroed in place; `over_hole` says so), and is asked again next step.

    Contacts are body-frame points (n, m, 2) at the new heading; c't-Sim places the skid at the
    new position but the wheels at the old one (`anchored`), so a skid stops at the edge and the
    robot drives off again, while wheels are checked a step late, end over the hole and keep
    every later move refused (c't-Sim's "falling"). Returns whether any robot's `over_hole` changed."""
    changed = False
    for i in range(pose.shape[0]):
        heading = pose[i, 2] + alpha[i]
        c, s = math.cos(heading), math.sin(heading)
        held = False
        for k in range(contacts.shape[1]):
            x, y = pose[i, 0], pose[i, 1]
            if not anchored[i, k]:
                x, y = x + move[i, 0], y + move[i, 1]
            px, py = contacts[i, k, 0], contacts[i, k, 1]
            held |= in_hole(x + c * px - s * py, y + s * px + c * py, hole, origin, cell, outside_is_hole)
        changed |= over_hole[i] != held
        over_hole[i] = held
        if held:
            move[i, 0] = move[i, 1] = alpha[i] = 0.0
    return changed


@numba.njit(cache=True)
def absorption_at(x: float, y: float, absorption: np.ndarray, origin: np.ndarray, cell: float, outside: np.float32) -> np.float32:
    """What the floor swallows at the point (x, y) (m) (`outside` off the map)."""
    ix, iy = raster_cell(x, y, origin, cell)
    if ix < 0 or iy < 0 or iy >= absorption.shape[0] or ix >= absorption.shape[1]:
        return outside
    return absorption[iy, ix]
