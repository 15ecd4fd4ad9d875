"""World files: the c't-Sim parcours importer against its ASCII grids, the shipped worlds, and
the TOML grid shorthand meaning the same world as the XML."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from shared_data import PARCOURS
from shared_data import needs_parcours as needs_shared

from sim.world.files import check_world, load_world, shipped_worlds
from sim.world.files.geometry import bbox, inside
from sim.world.spec import WorldFileError, WorldSpec

CELL = 0.24


def _world_files() -> list:
    if not PARCOURS.is_dir():
        return [pytest.param(None, marks=needs_shared)]
    return [p for p in sorted(PARCOURS.glob("*.xml")) if "<parcours" in p.read_text(encoding="utf-8", errors="replace")]


def _grid_rows(path: Path) -> list[str]:
    text = path.read_text(encoding="utf-8")
    return [chunk.split("</line>")[0] for chunk in text.split("<line>")[1:]]


def _boxes(pieces) -> set[tuple[float, ...]]:
    """Axis-aligned pieces as rounded (xmin, ymin, xmax, ymax)."""
    return {tuple(round(v, 6) for v in bbox(p.vertices)) for p in pieces}


def _cell(c: int, r: int, w: int = 1, h: int = 1) -> tuple[float, ...]:
    return tuple(round(v, 6) for v in (c * CELL, r * CELL, (c + w) * CELL, (r + h) * CELL))


def _centre(c: int, r: int) -> tuple[float, float]:
    return ((c + 0.5) * CELL, (r + 0.5) * CELL)


def _rounded(points) -> tuple:
    return tuple((round(x, 6), round(y, 6)) for x, y in points)


@pytest.mark.parametrize("path", _world_files(), ids=lambda p: p.name if p else "none")
def test_every_ctsim_parcours_loads(path: Path) -> None:
    world = load_world(path)
    rows = _grid_rows(path)
    assert world.bounds == pytest.approx((0, 0, max(map(len, rows)) * CELL, len(rows) * CELL))
    assert world.outside_is_hole
    assert world.starts, "every shipped parcours has a start tile"
    xmin, ymin, xmax, ymax = world.bounds
    for piece in (*world.walls, *world.holes, *world.goals, *world.floor):
        for x, y in piece.vertices:
            assert xmin - 1e-9 <= x <= xmax + 1e-9 and ymin - 1e-9 <= y <= ymax + 1e-9
    # every wall tile is covered by exactly one wall box
    walls = sum(row.count(ch) for row in rows for ch in "X=#*")
    covered = sum(round((b[2] - b[0]) * (b[3] - b[1]) / CELL**2) for b in _boxes(world.walls))
    assert covered == walls
    assert len(world.lights) == sum(row.count("*") for row in rows)
    assert isinstance(check_world(path), list)


@needs_shared
def test_optics_only_file_is_a_clean_error() -> None:
    with pytest.raises(WorldFileError, match="no <parcours> section") as err:
        load_world(PARCOURS / "defaultoptics.xml")
    assert err.value.path.endswith("defaultoptics.xml")


@needs_shared
def test_winzig_against_its_grid() -> None:
    # #####  row 6
    # #ZZZ#  row 5
    # *   *  row 4
    # #   #  row 3
    # *. .*  row 2
    # #1 2#  row 1
    # #####  row 0
    world = load_world(PARCOURS / "winzig.xml")
    assert world.bounds == pytest.approx((0, 0, 5 * CELL, 7 * CELL))
    # the side columns are one box each, through their pillars; the '#' of rows 0 and 6 between them are single boxes
    expected = {_cell(0, 0, 1, 7), _cell(4, 0, 1, 7)} | {_cell(c, r) for c in (1, 2, 3) for r in (0, 6)}
    assert _boxes(world.walls) == expected
    assert _rounded(sorted(light.position for light in world.lights)) == _rounded(
        sorted([_centre(0, 2), _centre(0, 4), _centre(4, 2), _centre(4, 4)])
    )
    assert all(light.height == 0.5 for light in world.lights)
    starts = {s.slot: s for s in world.starts}
    assert set(starts) == {1, 2}
    assert (starts[1].x, starts[1].y) == pytest.approx(_centre(1, 1))
    assert (starts[2].x, starts[2].y) == pytest.approx(_centre(3, 1))
    assert starts[1].heading == pytest.approx(math.pi / 2)  # the '.' is north of it
    assert starts[2].heading == pytest.approx(math.pi / 2)
    assert _boxes(world.goals) == {_cell(c, 5) for c in (1, 2, 3)}
    white = (1.0, 1.0, 1.0)
    floors = {tuple(round(v, 6) for v in bbox(f.vertices)): f.colour for f in world.floor}
    assert floors[_cell(1, 5, 3, 1)] == pytest.approx((0x66 / 255, 1.0, 0.0))  # ZZZ merged into one region
    assert floors[_cell(1, 2)] == white and floors[_cell(3, 2)] == white
    assert floors[_cell(1, 1)] == pytest.approx((0x99 / 255, 0x30 / 255, 0x30 / 255))
    assert not world.holes and not world.lines
    assert world.start_for(0) == starts[1]


@needs_shared
def test_template_against_its_grid() -> None:
    # r8 *===========*
    # r7 #     /-\   #
    # r6 #/\   |l|   #
    # r5 #(|/_T-%~   Z
    # r4 #|+~ |    ==#
    # r3 #|  p!q X o L
    # r2 #| #}[{XXX  #
    # r1 #|.#b]d   .2#
    # r0 *10=========*
    world = load_world(PARCOURS / "template.xml")
    walls = _boxes(world.walls)
    assert _cell(0, 8, 13, 1) in walls  # *===========* is one box, pillars included
    assert _cell(3, 0, 10, 1) in walls  # =========* takes the corner pillar
    assert _cell(0, 0, 1, 8) in walls  # the left column, from the lower pillar up to the top run
    assert {_cell(8, 3), _cell(7, 2), _cell(8, 2), _cell(9, 2)} <= walls  # X blocks, one box each
    assert _cell(3, 1, 1, 2) in walls  # the '#' in rows 1-2 of column 3
    assert _boxes(world.holes) == {_cell(12, 3)}
    assert _boxes(world.goals) == {_cell(12, 5)}
    assert _rounded(sorted(m.position for m in world.movables)) == _rounded(
        sorted(_centre(c, r) for c, r in [(1, 5), (4, 5), (4, 3), (6, 3), (10, 3), (4, 1), (6, 1)])
    )
    starts = {s.slot: s for s in world.starts}
    assert (starts[1].x, starts[1].y, starts[1].heading) == pytest.approx((*_centre(1, 0), 0.0))  # no '.' next to it: +x
    assert (starts[0].x, starts[0].y, starts[0].heading) == pytest.approx((*_centre(2, 0), math.pi / 2))
    assert (starts[2].x, starts[2].y, starts[2].heading) == pytest.approx((*_centre(11, 1), math.pi))

    lines = {_rounded(line.points) for line in world.lines}
    w = 0.1 * CELL
    cx, cy = _centre(6, 7)  # '/': east and south arms, each half a width past the centre (a square corner)
    assert _rounded([(cx - w / 2, cy), (cx + CELL / 2, cy)]) in lines
    assert _rounded([(cx, cy + w / 2), (cx, cy - CELL / 2)]) in lines
    cx, cy = _centre(5, 3)  # '!': vertical with a gap of one line width at the centre
    assert _rounded([(cx, cy + w / 2), (cx, cy + CELL / 2)]) in lines
    assert _rounded([(cx, cy - w / 2), (cx, cy - CELL / 2)]) in lines
    assert _rounded([(cx, cy - CELL / 2), (cx, cy + CELL / 2)]) not in lines
    cx, cy = _centre(5, 5)  # 'T': a full horizontal and a stem down
    assert _rounded([(cx + CELL / 2, cy), (cx - CELL / 2, cy)]) in lines
    assert _rounded([(cx, cy + w / 2), (cx, cy - CELL / 2)]) in lines
    cx, cy = _centre(5, 2)  # '[': a full cross
    assert _rounded([(cx, cy + CELL / 2), (cx, cy - CELL / 2)]) in lines
    assert _rounded([(cx + CELL / 2, cy), (cx - CELL / 2, cy)]) in lines
    assert all(line.width == pytest.approx(0.024) and line.colour == (0, 0, 0) and line.flat for line in world.lines)


@needs_shared
def test_toml_grid_and_xml_give_the_same_world(tmp_path: Path) -> None:
    rows = "\n".join(_grid_rows(PARCOURS / "template.xml"))
    toml = tmp_path / "template.toml"
    toml.write_text(f"outside_is_hole = true\n[grid]\ncell = 0.24\nrows = '''\n{rows}\n'''\n", encoding="utf-8")
    from_xml = load_world(PARCOURS / "template.xml")
    from_toml = load_world(toml)
    # a parcours' lines lie 1 mm above its floor, as c't-Sim's line tiles do; a TOML world's lie flat
    same = dataclasses.replace(from_toml, name=from_xml.name, source=from_xml.source, description=from_xml.description, line_height=from_xml.line_height)
    assert from_toml.line_height == 0.0 and same == from_xml


@needs_shared
def test_start_heading_follows_the_dot_neighbour() -> None:
    # testparcours4: '0' has its '.' to the south; testparcours5: '1' has '.' west and east (west wins)
    starts = {s.slot: s for s in load_world(PARCOURS / "testparcours4.xml").starts}
    assert starts[0].heading == pytest.approx(-math.pi / 2)
    starts = {s.slot: s for s in load_world(PARCOURS / "testparcours5.xml").starts}
    assert starts[1].heading == pytest.approx(math.pi)


def test_shipped_worlds_are_the_expected_set() -> None:
    assert {"empty", "square", "maze", "line", "holes_lights"} <= set(shipped_worlds())


@pytest.mark.parametrize("name", sorted(shipped_worlds()))
def test_every_shipped_world_loads_cleanly(name: str) -> None:
    world = load_world(name)
    assert world == load_world(shipped_worlds()[name])
    assert world.starts and world.walls
    assert world.name and world.description
    assert check_world(name) == []
    xmin, ymin, xmax, ymax = world.bounds
    start = world.start_for(0)
    assert xmin < start.x < xmax and ymin < start.y < ymax


def _maze_cells(world: WorldSpec) -> tuple[set, set, int, int]:
    """Wall and goal cells of a grid world, found by probing cell centres."""
    cols, rows = round(world.bounds[2] / CELL), round(world.bounds[3] / CELL)
    walls = {(c, r) for c in range(cols) for r in range(rows) if any(inside(_centre(c, r), w.vertices) for w in world.walls)}
    goals = {(c, r) for c in range(cols) for r in range(rows) if any(inside(_centre(c, r), g.vertices) for g in world.goals)}
    return walls, goals, cols, rows


@pytest.mark.parametrize("hand", [1, -1], ids=["right-hand", "left-hand"])
def test_maze_is_solved_by_a_wall_follower(hand: int) -> None:
    world = load_world("maze")
    walls, goals, cols, rows = _maze_cells(world)
    assert len(goals) == 1
    start = world.start_for(0)
    cell = (int(start.x // CELL), int(start.y // CELL))
    d = (round(math.cos(start.heading)), round(math.sin(start.heading)))
    for _ in range(4 * cols * rows):
        if cell in goals:
            break
        right = (d[1] * hand, -d[0] * hand)
        for turn in (right, d, (-right[0], -right[1]), (-d[0], -d[1])):
            ahead = (cell[0] + turn[0], cell[1] + turn[1])
            if ahead not in walls and 0 <= ahead[0] < cols and 0 <= ahead[1] < rows:
                cell, d = ahead, turn
                break
    assert cell in goals


def test_maze_corridors_fit_a_ctbot() -> None:
    world = load_world("maze")
    walls, _, cols, rows = _maze_cells(world)
    # c't-Sim style: whole-cell walls, so corridors are one 0.24 m cell, twice a c't-Bot's width
    assert len(walls) + sum(1 for _ in world.goals) < cols * rows
    start = world.start_for(0)
    assert (int(start.x // CELL), int(start.y // CELL)) not in walls


def test_line_course_is_closed_but_for_one_gap() -> None:
    world = load_world("line")
    (line,) = world.lines
    gap = math.dist(line.points[0], line.points[-1])
    assert 0.03 <= gap <= 0.1
    joints = [math.dist(a, b) for a, b in zip(line.points, line.points[1:])]
    assert max(joints) < 2.1 and min(joints) > 0
    start = world.start_for(0)
    assert min(math.dist((start.x, start.y), p) for p in line.points) < 1.0  # on the bottom straight


def test_holes_and_lights_world() -> None:
    world = load_world("holes_lights")
    assert len(world.holes) == 2 and len(world.lights) == 3
    start = world.start_for(0)
    lamp = world.lights[0].position
    assert math.atan2(lamp[1] - start.y, lamp[0] - start.x) == pytest.approx(start.heading)
    assert any(inside((1.42, 1.5), h.vertices) for h in world.holes)  # on the way to the lamp


@pytest.mark.parametrize("block", [0, 1])
def test_readme_examples_load(tmp_path: Path, block: int) -> None:
    readme = (Path(__file__).resolve().parents[1] / "worlds" / "README.md").read_text(encoding="utf-8")
    examples = [chunk.split("```")[0] for chunk in readme.split("```toml\n")[1:]]
    path = tmp_path / "example.toml"
    path.write_text(examples[block], encoding="utf-8")
    world = load_world(path)
    assert world.starts


@pytest.mark.parametrize(
    ("colours", "expected"),
    [
        ("<color type='ambient'>#606060</color><color type='diffuse'>#CCFFFF</color>", (0xCC / 255, 1.0, 1.0)),
        ("<color type='diffuse'>#CCFFFF</color><color type='ambient'>#606060</color>", (0xCC / 255, 1.0, 1.0)),
        ("<color>#606060</color>", (1.0, 1.0, 1.0)),  # an untyped colour is ambient: Java3D's default diffuse, white
    ],
)
def test_floor_takes_the_diffuse_colour_as_c_t_sims_sensors_read_it(tmp_path: Path, colours: str, expected: tuple) -> None:
    """c't-Sim's floor sensors read a material's diffuse colour, never its ambient one
    (`World.sensGroundReflectionCross`); held here on a file of our own, without ../shared
    (test_ctsim_fidelity holds it on c't-Sim's own worlds)."""
    path = tmp_path / "floor.xml"
    path.write_text(f"<world><parcours><line>#1 #</line></parcours><optics><appearance type=' '>{colours}</appearance></optics></world>")
    assert load_world(path).floor_colour == pytest.approx(expected, abs=0)
