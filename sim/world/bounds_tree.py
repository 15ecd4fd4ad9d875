"""Java3D's bounds tree over c't-Sim's scene, which its cone pick walks before it tests any shape.

c't-Sim's IR pick (`World.watchObstacle`: Java3D's `pickClosest` with a `PickConeSegment`) asks
the Java3D universe's bounds hierarchy (its `BHTree`, read in hharrison/java3d-core) for the
shapes the cone may meet: from the root down, a node's children are visited only if the cone
meets the node's bounding box (the same box test as for a shape's own bounds,
`kernels.pick.cone_meets_box`). A wall face beside the sensor whose corner lies in the cone is
skipped when the cone misses the box of a node holding it with other shapes, so c't-Sim sees
nothing there (checked against the tree of a running c't-Sim, dumped by reflection).

The tree is built as Java3D builds it: the scene's shapes (`WorldSpec.scene`, in the order they
go live) split in two at the mean of their bounds' centres along the axis where the centres
spread most (float arithmetic, as Java's), recursively; a bot added later goes into the deepest
node whose box holds its shapes' bounds and that node is split anew with it (`insert`). As the
bot moves, the boxes of the nodes above its shapes follow it (`kernels.pick.move_robot_leaves`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.world import layout
from sim.world.kernels.pick import CTBOT_BOTTOM, CTBOT_SHAPES, CTBOT_TOP, robot_boxes
from sim.world.spec import SceneShape


class _JavaRandom:
    """java.util.Random's boolean draws: Java3D's insertion picks a child with one (seeded 0)."""

    def __init__(self, seed: int = 0):
        self.seed = (seed ^ 0x5DEECE66D) & ((1 << 48) - 1)

    def next_boolean(self) -> bool:
        self.seed = (self.seed * 0x5DEECE66D + 0xB) & ((1 << 48) - 1)
        return (self.seed >> 47) != 0


@dataclass(eq=False)
class _Node:
    lower: np.ndarray
    upper: np.ndarray
    right: _Node | None = None
    left: _Node | None = None
    face: int = -1
    lamp: int = -1
    robot: int = -1
    parent: _Node | None = field(default=None, repr=False)

    @property
    def leaf(self) -> bool:
        return self.right is None and self.left is None

    def hull_from_children(self) -> None:
        assert self.right is not None and self.left is not None
        self.lower = np.minimum(self.right.lower, self.left.lower)
        self.upper = np.maximum(self.right.upper, self.left.upper)

    def holds(self, other: _Node) -> bool:
        """Java3D's `isInside`: this node's box contains `other`'s."""
        return bool(np.all(self.lower <= other.lower) and np.all(self.upper >= other.upper))


def _halves(count: int) -> list[bool]:
    """Left (True) or right, alternating from the left: Java3D's split when the mean splits nothing."""
    left = right = 0
    out = []
    for _ in range(count):
        out.append(left <= right)
        left, right = (left + 1, right) if out[-1] else (left, right + 1)
    return out


def _construct(parent: _Node, nodes: list[_Node], centres: np.ndarray) -> None:
    """Java3D's `BHTree.constructTree`: split `nodes` (centres (n, 3) float32) at the mean of the
    axis of the largest sum of squares, ties to the smaller side, into parent's two children."""
    f = np.float32
    n = len(nodes)
    total = np.zeros(3, np.float32)
    for i in range(n - 1, -1, -1):
        total = (total + centres[i]).astype(np.float32)
    means = (total / f(n)).astype(np.float32)
    squares = np.zeros(3, np.float32)
    for i in range(n - 1, -1, -1):
        temp = (centres[i] - means).astype(np.float32)
        squares = (squares + temp * temp).astype(np.float32)
    axis, largest = -1, f(0.0)
    for k in range(3):
        if squares[k] > largest:
            axis, largest = k, squares[k]
    if axis < 0:
        left = _halves(n)
    else:
        left, lefts, rights = [], 0, 0
        for i in range(n):
            c, m = centres[i, axis], means[axis]
            goes_left = bool(c < m) or (not c > m and lefts <= rights)
            left.append(goes_left)
            lefts, rights = (lefts + 1, rights) if goes_left else (lefts, rights + 1)
        if all(left) or not any(left):
            left = _halves(n)
    for side in (False, True):  # the right child first, as Java3D builds it
        members = [k for k in range(n) if left[k] == side]
        if len(members) == 1:
            child = nodes[members[0]]
        else:
            child = _Node(np.zeros(3), np.zeros(3))
            _construct(child, [nodes[k] for k in members], centres[members])
        child.parent = parent
        if side:
            parent.left = child
        else:
            parent.right = child
    parent.hull_from_children()


def _centres(nodes: Sequence[_Node]) -> np.ndarray:
    """Each node's bounds' centre as Java3D's `computeCenterValues`: (float)(upper + lower) / 2f."""
    return np.array([(n.upper + n.lower).astype(np.float32) / np.float32(2.0) for n in nodes], dtype=np.float32).reshape(-1, 3)


@dataclass
class BoundsTree:
    """Java3D's bounds tree of a scene, with bots inserted as they come (`insert_robot`); its
    arrays for the compiled pick by `kernel`."""

    root: _Node | None = None
    robot_leaves: list[list[_Node]] = field(default_factory=list)
    _random: _JavaRandom | None = None

    @classmethod
    def of_scene(cls, scene: Sequence[SceneShape]) -> BoundsTree:
        """The tree Java3D builds of the scene's shapes, all going live at once (`BHTree.create`)."""
        tree = cls()
        leaves = [_Node(np.array(s.lower, dtype=np.float64), np.array(s.upper, dtype=np.float64), face=s.face, lamp=s.lamp) for s in scene]
        if len(leaves) == 1:
            tree.root = leaves[0]
        elif leaves:
            tree.root = _Node(np.zeros(3), np.zeros(3))
            _construct(tree.root, leaves, _centres(leaves))
        return tree

    def insert_robot(self, robot: int, pose: tuple[float, float, float]) -> None:
        """Insert c't-Sim's bot shapes at `pose` (x, y m, heading rad) as Java3D inserts a bot
        added to the live scene (`BHTree.insert` with its `BHInsertStructure`)."""
        lower, upper = robot_bounds(pose)
        leaves = [_Node(lower[k], upper[k], robot=robot) for k in range(len(CTBOT_SHAPES))]
        while len(self.robot_leaves) <= robot:
            self.robot_leaves.append([])
        self.robot_leaves[robot] = leaves
        if self.root is None or self.root.leaf:
            nodes = leaves + ([self.root] if self.root is not None else [])
            self.root = _Node(np.zeros(3), np.zeros(3))
            _construct(self.root, nodes, _centres(nodes))
            return
        if self._random is None:
            self._random = _JavaRandom(0)
        pending: dict[int, tuple[_Node, list[_Node]]] = {}  # (Java3D's insert structure: per node, what joins it, in order)
        for leaf in leaves:
            if self.root.holds(leaf):
                self._descend(self.root, leaf, pending)
            else:
                self.root.lower, self.root.upper = np.minimum(self.root.lower, leaf.lower), np.maximum(self.root.upper, leaf.upper)
                pending.setdefault(id(self.root), (self.root, []))[1].append(leaf)
        for node, joining in pending.values():
            members = [*joining, node.left, node.right]
            for m in members[len(joining) :]:
                if not m.leaf:
                    m.hull_from_children()
            node.left = node.right = None
            _construct(node, members, _centres(members))

    def _descend(self, node: _Node, leaf: _Node, pending: dict[int, tuple[_Node, list[_Node]]]) -> None:
        """`BHInternalNode.insert`: down into the one inner child holding the leaf's box (a random
        one if both do), else the leaf joins this node."""
        in_left = not node.left.leaf and node.left.holds(leaf)
        in_right = not node.right.leaf and node.right.holds(leaf)
        if in_left and in_right:
            in_left = self._random.next_boolean()
            in_right = not in_left
        if in_left:
            self._descend(node.left, leaf, pending)
        elif in_right:
            self._descend(node.right, leaf, pending)
        else:
            pending.setdefault(id(node), (node, []))[1].append(leaf)

    def kernel(self, robots: int, spans: np.ndarray) -> layout.BoundsTree:
        """The tree as flat arrays (`layout.BoundsTree`), the root first, for ROBOTS robots and
        walls whose vertices SPANS (`layout.SPANS`) give."""
        nodes: list[_Node] = []
        stack = [self.root] if self.root is not None else []
        while stack:
            node = stack.pop()
            nodes.append(node)
            if not node.leaf:
                stack += [node.left, node.right]
        index = {id(n): i for i, n in enumerate(nodes)}
        face = np.array([n.face for n in nodes], dtype=np.int64)
        tree = layout.BoundsTree(
            lower=np.array([n.lower for n in nodes], dtype=np.float64).reshape(-1, 3),
            upper=np.array([n.upper for n in nodes], dtype=np.float64).reshape(-1, 3),
            kids=np.array([(-1, -1) if n.leaf else (index[id(n.right)], index[id(n.left)]) for n in nodes], dtype=np.int64).reshape(-1, 2),
            parent=np.array([index[id(n.parent)] if n.parent is not None else -1 for n in nodes], dtype=np.int64),
            face=face,
            wall=np.where(face >= 0, np.searchsorted(spans["end"], face, side="right"), -1).astype(np.int64),
            lamp=np.array([n.lamp for n in nodes], dtype=np.int64),
            robot_leaves=np.full((robots, len(CTBOT_SHAPES)), -1, dtype=np.int64),
        )
        for r, leaves in enumerate(self.robot_leaves[:robots]):
            for k, leaf in enumerate(leaves):
                tree.robot_leaves[r, k] = index[id(leaf)]
        return tree


def robot_bounds(pose: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Java3D's bounds of c't-Sim's bot shapes at `pose` (`kernels.pick.robot_boxes`): (lower, upper), each (shapes, 3)."""
    lower, upper = np.empty((len(CTBOT_SHAPES), 3)), np.empty((len(CTBOT_SHAPES), 3))
    robot_boxes(*pose, CTBOT_SHAPES, CTBOT_BOTTOM, CTBOT_TOP, lower, upper)
    return lower, upper
