"""Compiled lookups in the floor raster (`sim.world.layout.Floor`, from `sim.world.floor.FloorMap`):
the one test of a point over a hole (`in_hole`, also behind `FloorMap.hole_at` and a chassis's
second mouse), the absorption at a point, and c't-Sim's ground-contact rule (`hold_at_holes`)."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import INNER
from sim.world.layout import Floor, Ground


@numba.njit(cache=True, inline="always")
def raster_cell(x: float, y: float, floor: Floor) -> tuple[int, int]:
    """The raster's column and row of the point (x, y) (m), unclamped: off the map beyond its shape."""
    return int(math.floor((x - floor.origin[0]) / floor.cell)), int(math.floor((y - floor.origin[1]) / floor.cell))


@numba.njit(cache=True, inline="always")
def in_hole(x: float, y: float, floor: Floor) -> bool:
    """Whether the point (x, y) (m) is over a hole (off the map: `outside_is_hole`): the one hole
    test of the world, its kernels and its Python code alike."""
    ix, iy = raster_cell(x, y, floor)
    if ix < 0 or iy < 0 or iy >= floor.hole.shape[0] or ix >= floor.hole.shape[1]:
        return floor.outside_is_hole
    return floor.hole[iy, ix]


@numba.njit(cache=True, inline="always")
def raster_at(x: float, y: float, raster: np.ndarray, origin_x: float, origin_y: float, cell: float, outside: np.float32) -> np.float32:
    """One of the floor's float32 rasters (`Floor.ground`, `Floor.lines`) at the point (x, y) (m),
    `outside` off the map: the sensors' lookup, given the one raster and the frame as plain values
    (a call that passes the whole Floor group counts a reference for each of its arrays, which cost
    the floor sensors half their time)."""
    ix, iy = int(math.floor((x - origin_x) / cell)), int(math.floor((y - origin_y) / cell))
    if ix < 0 or iy < 0 or iy >= raster.shape[0] or ix >= raster.shape[1]:
        return outside
    return raster[iy, ix]


@numba.njit(cache=True, **INNER)
def hold_at_holes(pose: np.ndarray, state: np.ndarray, ground: Ground, floor: Floor) -> bool:
    """c't-Sim's ground-contact rule (`MasterSimulator`, "Bodenkontakt"): a robot whose planned
    move and turn (STATE's move, alpha) would bring a ground contact over a hole neither moves nor
    turns this step (both zeroed in place; `ground.fallen` says so), and is asked again next step.

    Contacts are body-frame points at the new heading; c't-Sim places the skid at the new position
    but the wheels at the old one (`ground.anchored`), so a skid stops at the edge and the robot
    drives off again, while wheels are checked a step late, end over the hole and keep every later
    move refused (c't-Sim's "falling"). Returns whether any robot's `fallen` changed."""
    changed = False
    contacts, anchored, fallen = ground.contacts, ground.anchored, ground.fallen
    for i in range(pose.shape[0]):
        move = state[i].move
        heading = pose[i, 2] + state[i].alpha
        c, s = math.cos(heading), math.sin(heading)
        held = False
        for k in range(contacts.shape[1]):
            x, y = pose[i, 0], pose[i, 1]
            if not anchored[i, k]:
                x, y = x + move[0], y + move[1]
            px, py = contacts[i, k, 0], contacts[i, k, 1]
            held |= in_hole(x + c * px - s * py, y + s * px + c * py, floor)
        changed |= fallen[i] != held
        fallen[i] = held
        if held:
            move[0] = move[1] = 0.0
            state[i].alpha = 0.0
    return changed
