"""Java3D's bounds tree over c't-Sim's scene (`sim.world.bounds_tree`), which c't-Sim's IR pick walks
before it tests any wall face."""

from __future__ import annotations

import math

import pytest

from bots.ctbot import CTBOT
from sim.bridge.session import as_in_ctsim
from sim.world import World
from sim.world.bounds_tree import BoundsTree
from sim.world.files import load_world
from sim.world.kernels.pick import pick_wall
from sim.world.spec import SceneShape


def leaf_sets(node) -> list[frozenset[float]]:
    """Each inner node's leaves, by their lower x, right child first."""
    if node.leaf:
        return []
    below = leaf_sets(node.right) + leaf_sets(node.left)
    return [frozenset(float(n.lower[0]) for n in leaves(node)), *below]


def leaves(node):
    return [node] if node.leaf else leaves(node.right) + leaves(node.left)


def test_the_tree_splits_at_the_mean_centre_along_the_axis_of_widest_spread_ties_to_the_smaller_side():
    """Four unit boxes in a row at x 0, 1, 2 and 10: the centres spread along x only, their mean
    3.75 parts {0, 1, 2} from {10}; of those the mean 1.5 (the centres 0.5, 1.5, 2.5) meets the
    middle one, which goes to the side with fewer so far (the right: the first went left)."""
    scene = [SceneShape((x, 0.0, 0.0), (x + 1.0, 1.0, 1.0)) for x in (0.0, 1.0, 2.0, 10.0)]
    tree = BoundsTree.of_scene(scene)
    assert [n.lower[0] for n in leaves(tree.root.right)] == [10.0]
    assert sorted(n.lower[0] for n in leaves(tree.root.left.right)) == [1.0, 2.0]
    assert [n.lower[0] for n in leaves(tree.root.left.left)] == [0.0]
    assert tree.root.lower.tolist() == [0.0, 0.0, 0.0] and tree.root.upper.tolist() == [11.0, 1.0, 1.0]


PARCOURS = """<?xml version="1.0" encoding="UTF-8"?>
<world><parcours>
<line>=========</line>
<line>#       #</line>
<line>#X      #</line>
<line>#X      #</line>
<line>#       #</line>
<line>#X      #</line>
<line>#      1#</line>
<line>=========</line>
</parcours></world>
"""


def test_the_pick_skips_a_wall_face_when_the_cone_misses_its_tree_node(tmp_path):
    """A sensor 2 mm east of a column of two wall blocks (x 0.24..0.48, y 0.96..1.44), 60 mm south
    of it, looking north: the blocks' south-east corner lies 2 mm beside the axis, inside the 3°
    cone (3.1 mm there), and inside the box of the face it ends, so the faces alone read that
    corner at hypot(0.002, 0.06) m. But Java3D's tree holds that face in the node of the room's
    west strip (the west wall and the three blocks: x 0..0.48, y 0..1.92), whose box ends 2 mm west
    of the sensor and reaches from behind it to past the cone's end: the cone meets none of the
    box's upright edges, nor does the axis ray meet the box, and the pick sees the wall across the
    room, 0.78 m ahead (the real c't-Sim reads the same). Turned 0.02 rad west, the axis ray meets
    the node's box further on and the corner is seen."""
    path = tmp_path / "column.xml"
    path.write_text(PARCOURS)
    world = World(load_world(path, pillars="cylinder"))
    me = world.add_robot(as_in_ctsim(CTBOT))
    sensor, cone = (0.482, 0.90), math.radians(3.0)
    corner = math.hypot(0.002, 0.06)
    assert math.atan2(0.002, 0.06) < cone  # the corner is in the cone
    walls = world._walls
    alone = min(pick_wall((*sensor, 0.0, 1.0, 0.85), math.tan(cone), walls.vertices, a, b, c)
                for a, b, c in zip(walls.spans["start"], walls.spans["end"], walls.boxes["cylinder"]))  # fmt: skip
    assert alone == pytest.approx(corner, abs=1e-12)
    across = world.ray_distance(me, sensor, math.pi / 2, cone=cone, pick=True)
    assert 0.78 <= across < 0.7802  # the north wall's face 0.78 m ahead (read near its diagonal: `kernels.pick`)
    assert world.ray_distance(me, sensor, math.pi / 2 + 0.02, cone=cone, pick=True) == pytest.approx(corner, abs=1e-12)
