"""Issue 16: the robots' pymunk bodies read and written as arrays (`sim.world.bodies`) give what the
bodies' own properties say, with movable obstacles and the static walls in the same space."""

from __future__ import annotations

import numpy as np
import pymunk
import pymunk.batch as batch
import pytest

from sim.world import layout
from sim.world.bodies import _POSE, BodyArrays, _Walk


def space_with_everything(robots: int, cans: int) -> tuple[pymunk.Space, list[pymunk.Body], list[pymunk.Body]]:
    """Cans added first, robots after, a wall on the static body: robots' rows are not 0..n-1."""
    rng = np.random.default_rng(robots * 10 + cans)
    space = pymunk.Space()
    space.add(pymunk.Poly(space.static_body, [(5, 5), (6, 5), (6, 6)]))

    def body(kind: str) -> pymunk.Body:
        b = pymunk.Body(0.05 if kind == "can" else 1.0, 0.01)
        b.position = tuple(rng.uniform(-3, 3, 2))
        b.angle = float(rng.uniform(-10, 10))
        b.velocity = tuple(rng.uniform(-1, 1, 2))
        b.angular_velocity = float(rng.uniform(-1, 1))
        space.add(b, pymunk.Circle(b, 0.05))
        return b

    cans_ = [body("can") for _ in range(cans)]
    robots_ = [body("robot") for _ in range(robots)]
    return space, robots_, cans_


def test_poses_are_the_bodies_positions_and_angles() -> None:
    for robots, cans in ((1, 0), (5, 0), (3, 4)):
        space, bodies, _ = space_with_everything(robots, cans)
        expected = [[b.position.x, b.position.y, b.angle] for b in bodies]
        assert BodyArrays(space, bodies).poses().tolist() == expected


def test_poses_follow_the_bodies_and_are_new_arrays() -> None:
    """`poses` reads pymunk's buffer into a new array each time: a pose read before a move keeps its values."""
    for robots, cans in ((1, 0), (3, 4)):
        space, bodies, _ = space_with_everything(robots, cans)
        arrays = BodyArrays(space, bodies)
        before = arrays.poses()
        kept = before.copy()
        for b in bodies:
            b.position, b.angle = b.position + (0.25, -0.5), b.angle + 1.0
        assert arrays.poses().tolist() == [[b.position.x, b.position.y, b.angle] for b in bodies]
        assert np.array_equal(before, kept)


def test_place_sets_what_the_bodies_own_setters_set() -> None:
    """`place` (pymunk's batch setter, called per robot body) leaves each robot as setting its
    `position` then its `angle` does: the same position, angle and transform; the cans stay."""
    for robots, cans in ((1, 0), (3, 4)):
        placed, bodies, others = space_with_everything(robots, cans)
        public, same_bodies, _ = space_with_everything(robots, cans)
        kept = [(tuple(b.position), b.angle) for b in others]
        poses = np.random.default_rng(robots).uniform(-4, 4, (robots, 3))
        BodyArrays(placed, bodies).place(poses)
        for b, (x, y, angle) in zip(same_bodies, poses.tolist()):
            b.position = (x, y)
            b.angle = angle
        assert [(tuple(b.position), b.angle, tuple(b.rotation_vector), tuple(b.local_to_world((0.3, -0.7)))) for b in bodies] == [
            (tuple(b.position), b.angle, tuple(b.rotation_vector), tuple(b.local_to_world((0.3, -0.7)))) for b in same_bodies
        ]
        assert [(tuple(b.position), b.angle) for b in others] == kept


def test_send_sets_the_robots_and_keeps_the_cans() -> None:
    for robots, cans in ((1, 0), (4, 3)):
        space, bodies, others = space_with_everything(robots, cans)
        arrays = BodyArrays(space, bodies)
        kept = [(tuple(b.velocity), b.angular_velocity) for b in others]
        force = np.arange(2.0 * robots).reshape(robots, 2) + 0.5
        torque = -np.arange(1.0 * robots) - 0.25
        for _ in range(2):  # a second push meets the state the first left
            arrays.refresh()
            arrays.motion[arrays.row_index, 3:5] = force
            arrays.motion[arrays.row_index, 5] = torque
            arrays.send()
            assert [(tuple(b.velocity), b.angular_velocity) for b in others] == kept
            for k, b in enumerate(bodies):
                assert tuple(b.velocity) == (0.0, 0.0) and b.angular_velocity == 0.0
                assert tuple(b.force) == tuple(force[k]) and b.torque == torque[k]


def test_the_private_walk_reads_what_pymunk_batch_reads():
    """`_Walk` reads pymunk's private names (pinned to pymunk 7.3.x): it gives the floats of
    `pymunk.batch.get_space_bodies` for the same fields, in the same order."""
    space, _, _ = space_with_everything(4, 3)
    for fields, width in ((_POSE, 3), (layout.MOTION_FIELDS, 6)):
        walk = _Walk(space, fields, batch.Buffer(), write=False, width=width)
        walk()
        public = batch.Buffer()
        batch.get_space_bodies(space, fields, public)
        assert np.array_equal(walk.floats(), np.frombuffer(public.float_buf()).reshape(-1, width))


def test_the_motion_rows_are_named_after_pymunk_batch_fields():
    """MOTION's fields are pymunk's BodyFields of MOTION_FIELDS, in the order pymunk walks them (its flags' order)."""
    names = [field.name.lower() for field in batch.BodyFields if field in layout.MOTION_FIELDS and field is not layout.MOTION_FIELDS]
    assert names == [field.name for field in layout.MOTION.fields]


def test_step_moves_every_body_as_pymunks_own_step() -> None:
    """`BodyArrays.step` (pymunk's C step without its Python wrapper) leaves every body where
    `space.step` leaves it, contacts and a begin callback included; work pymunk's wrapper does after
    a step (something added during it) is refused rather than dropped."""
    moved = []
    for fast in (False, True):
        space, bodies, cans = space_with_everything(3, 4)
        touched = []
        space.on_collision(None, None, begin=lambda arbiter, space, data, touched=touched: touched.append(1))
        for b in bodies + cans:  # all towards the origin, where they meet after a second
            b.velocity = (-b.position.x, -b.position.y)
        arrays = BodyArrays(space, bodies)
        for _ in range(300):
            arrays.step(0.01) if fast else space.step(0.01)
        moved.append(([(*b.position, b.angle, *b.velocity) for b in bodies + cans], len(touched)))
    assert moved[0] == moved[1] and moved[0][1] > 0
    space, bodies, _ = space_with_everything(1, 0)
    arrays = BodyArrays(space, bodies)
    space.add(pymunk.Body(1.0, 1.0))  # a body added outside a step is checked by pymunk's own step
    arrays.step(0.01)
    space.on_collision(None, None, begin=lambda arbiter, space, data: space.add(pymunk.Body(1.0, 1.0)))
    bodies[0].position, bodies[0].velocity = (5.5, 5.2), (0.0, 0.0)  # inside the wall: a contact begins
    with pytest.raises(RuntimeError, match="during the step"):
        arrays.step(0.01)
