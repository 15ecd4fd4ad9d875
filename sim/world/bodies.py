"""The robots' pymunk bodies read and written as arrays, one C call per step instead of a Python
loop of property accesses per robot (`pymunk.batch`).

pymunk's batch functions walk every dynamic body of the space (robots and movable obstacles) in
the space's own order; `BodyArrays` keeps the row of each robot in that walk, and writes back
the other bodies' values unchanged.

`_Walk` reads pymunk 7.3's private names (`pymunk._chipmunk`'s ffi and lib, `Buffer._float_arr`
and `_int_arr`, `Space._space`, `Body._body`; pymunk's `batch` module says they may change in
patch versions), `BodyArrays.step` the `Space`'s bookkeeping around a step (`_locked`,
`_bodies_to_check`, `_add_later`, `_remove_later`, `_post_step_callbacks`, `_removed_shapes`): pyproject.toml pins pymunk to 7.3.x, and tests/test_bodies.py holds the walk
equal to `pymunk.batch.get_space_bodies`.
"""

from __future__ import annotations

import numpy as np
import pymunk
import pymunk.batch as batch
from pymunk._chipmunk import ffi, lib  # the C layer under pymunk.batch (see _Walk): pymunk 7.3.x, pinned

from sim.world.layout import MOTION, MOTION_FIELDS, motion_rows

_POSE = batch.BodyFields.POSITION | batch.BodyFields.ANGLE


class _Walk:
    """One of pymunk.batch's walks over a space's bodies (reading or writing `fields` through
    `buffer`), its C call data built once: `batch.get_space_bodies` and `set_space_bodies` build
    it anew on every call, which cost about 1 us each, twice a world step."""

    def __init__(self, space: pymunk.Space, fields: batch.BodyFields, buffer: batch.Buffer, write: bool, width: int = 1):
        self._owners = space, buffer  # (the C space and arrays live as long as these)
        self._width = width
        self._seen: tuple = (None, -1)  # the C array and count `_view` was made for
        self._view = np.empty((0, width))
        self._space = space._space
        self._floats = buffer._float_arr
        self._data = ffi.new("pmBatchedData *")
        self._data.fields = fields.value
        self._data.floatArray = buffer._float_arr
        self._data.intArray = buffer._int_arr
        name = "pmSpaceBodySetIteratorFuncBatched" if write else "pmSpaceBodyGetIteratorFuncBatched"
        self._visit, self._visit_one = ffi.addressof(lib, name), getattr(lib, name)

    def __call__(self) -> None:
        self._floats.num = 0  # reading: append from the start; writing: read from the start
        lib.cpSpaceEachBody(self._space, self._visit, self._data)

    def each(self, bodies: list) -> None:
        """The walk's visit of the given C bodies alone, in their order (the buffer's rows are theirs)."""
        self._floats.num = 0
        visit, data = self._visit_one, self._data
        for body in bodies:
            visit(body, data)

    def floats(self) -> np.ndarray:
        """The values the last read walk gave, one row of `width` per body (a view into pymunk's
        buffer: valid until the next walk). The view is made again only when the buffer moved or
        changed size, which costs more than the walk itself."""
        seen = self._floats.arr, self._floats.num
        if seen != self._seen:
            self._seen = seen
            self._view = np.frombuffer(ffi.buffer(seen[0], 8 * seen[1])).reshape(-1, self._width)
        return self._view


class BodyArrays:
    """Poses of, and forces on, the given robot bodies of `space` (built once the bodies are in)."""

    def __init__(self, space: pymunk.Space, bodies: list[pymunk.Body]):
        self.space = space
        ids = batch.Buffer()
        batch.get_space_bodies(space, batch.BodyFields.BODY_ID, ids)
        order = np.frombuffer(ids.int_buf(), dtype=np.uintp)
        row = {body_id: k for k, body_id in enumerate(order.tolist())}
        rows = np.array([row[body.id] for body in bodies], dtype=np.int64)
        robots = {body.id for body in bodies}
        self._others = any(body.id not in robots for body in space.bodies)
        """Movable obstacles are walked too: their velocities and forces are read and written back
        every step (the static body's never change: read once here)."""
        consecutive = len(rows) > 0 and np.array_equal(rows, np.arange(rows[0], rows[0] + len(rows)))
        self.rows = slice(int(rows[0]), int(rows[0]) + len(rows)) if consecutive else rows
        """Each robot's row in pymunk's walk over the bodies (consecutive rows: a slice, cheaper)."""
        self.row_index = rows
        """The same rows as an array (for compiled kernels)."""
        self._robot_bodies = bodies  # (the C bodies below live as long as these)
        self._c_bodies = [body._body for body in bodies]
        self._read_pose = _Walk(space, _POSE, batch.Buffer(), write=False, width=3)
        self._read_pose()
        self._robot_poses = self._read_pose.floats()[self.rows] if isinstance(self.rows, slice) else None
        """The robots' rows of the pose walk's buffer (a view; None for rows by an index array): the
        walk fills the same C array every step, as the bodies are those of the space now."""
        self._placed = np.zeros((len(bodies), 3))
        placing = batch.Buffer()
        placing.set_float_buf(self._placed)  # pymunk reads this array in place
        self._place = _Walk(space, _POSE, placing, write=True)
        self._read_motion = _Walk(space, MOTION_FIELDS, batch.Buffer(), write=False, width=MOTION.dtype.itemsize // 8)
        self._read_motion()
        self.motion = self._read_motion.floats().copy()
        """MOTION rows (velocity, angular velocity, force, torque) per body as floats, as `send` writes
        them: the robots' rows at rest."""
        self._at_rest()
        written = batch.Buffer()
        written.set_float_buf(self.motion)  # pymunk reads this array in place
        self._write_motion = _Walk(space, MOTION_FIELDS, written, write=True)

    def _at_rest(self) -> None:
        """The robots' velocities in `motion` zero: they enter pymunk's step at rest (`World._apply_motion`)."""
        rows = motion_rows(self.motion)
        rows["velocity"][self.rows] = 0.0
        rows["angular_velocity"][self.rows] = 0.0

    def poses(self) -> np.ndarray:
        """(n, 3) robot poses (x, y m; heading rad), a new array."""
        self._read_pose()
        if self._robot_poses is not None:
            return self._robot_poses.copy()
        return self._read_pose.floats()[self.rows]  # (rows by an index array: a copy already)

    def refresh(self) -> None:
        """Take the other bodies' current velocities and forces into `motion` (call before writing
        the robots' forces into it); nothing to do without other bodies."""
        if self._others:
            self._read_motion()
            self.motion[:] = self._read_motion.floats()
            self._at_rest()  # (without them, the robots' velocities stay the zeros set above)

    def move(self, dt: float) -> None:
        """pymunk's position update (`Body.update_position`) of every robot body, by its C function
        (the Python wrapper cost as much again, per robot and step)."""
        update = lib.cpBodyUpdatePosition
        for body in self._c_bodies:
            update(body, dt)

    def place(self, poses: np.ndarray) -> None:
        """Put the robot bodies at `poses` (n, 3) as pymunk's position update would: pymunk's batch
        setter of position and angle, one C call per robot body (the Python wrappers of
        `cpBodySetPosition` and `cpBodySetAngle` cost half as much again), which leaves the same
        position, angle and transform (tests/test_bodies.py)."""
        self._placed[...] = poses
        self._place.each(self._c_bodies)

    def step(self, dt: float) -> None:
        """`space.step(dt)` by its C function alone where pymunk's wrapper has nothing to do around
        it (no body to check before, nothing added, removed or called back after: every step of a
        World, whose collision callback only counts), a fifth of a lone robot's step otherwise
        (about 1 µs); else, and where a step left such work after all (RuntimeError), pymunk's own."""
        space = self.space
        if space._bodies_to_check or space._add_later or space._remove_later or space._post_step_callbacks or space.threaded:
            space.step(dt)
            return
        space._locked = True
        try:
            lib.cpSpaceStep(space._space, dt)
            space._removed_shapes.clear()
        finally:
            space._locked = False
        if space._add_later or space._remove_later or space._post_step_callbacks:
            raise RuntimeError("a pymunk callback added, removed or scheduled something during the step: step with space.step")

    def send(self) -> None:
        """Give every body its row of `motion`: the robots at rest with the forces and torques
        written into their rows, the other bodies as `refresh` found them."""
        self._write_motion()
