"""Importer for c't-Sim parcours XML: `<world><description/><parcours><line>…</line>…</parcours>
<optics><appearance type="c">…</appearance></optics></world>` (ctsim-reference.md §3).

expat is used directly because ElementTree keeps no line numbers and an error must name the line
of the offending `<line>`. The DOCTYPE's `parcours.dtd` is never fetched.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from sim.world.spec import Colour, WorldFileError, WorldSpec

from .grid import DEFAULT_CELL, DEFAULT_TILE_COLOURS, build_grid


@dataclass
class _Element:
    tag: str
    attrs: dict[str, str]
    line: int
    text: str = ""
    children: list[_Element] = field(default_factory=list)

    def all(self, tag: str) -> list[_Element]:
        return [e for e in self.children if e.tag == tag]

    def first(self, tag: str) -> _Element | None:
        return next(iter(self.all(tag)), None)


def _parse_xml(data: bytes, path: Path) -> _Element:
    """A minimal element tree with each element's start line; expat errors become WorldFileError."""
    parser = expat.ParserCreate()
    stack: list[_Element] = [_Element("", {}, 0)]

    def start(tag: str, attrs: dict[str, str]) -> None:
        element = _Element(tag, attrs, parser.CurrentLineNumber)
        stack[-1].children.append(element)
        stack.append(element)

    def end(tag: str) -> None:
        stack.pop()

    def text(data: str) -> None:
        stack[-1].text += data

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        raise WorldFileError(path, e.lineno, f"XML error: {expat.ErrorString(e.code)}") from None
    return stack[0].children[0]


def load_parcours(path: Path) -> WorldSpec:
    """Load a c't-Sim parcours file; everything outside the map is a hole, as in c't-Sim."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise WorldFileError(path, None, f"cannot read: {e.strerror}") from None
    root = _parse_xml(data, path)
    parcours = root.first("parcours")
    if root.tag != "world" or parcours is None:
        raise WorldFileError(path, root.line, f"not a parcours: <{root.tag}> has no <parcours> section")
    rows = parcours.all("line")
    if not rows:
        raise WorldFileError(path, parcours.line, "<parcours> has no <line>")
    # <optics> sits beside <parcours> in real files, inside it per the DTD: accept both.
    optics = root.first("optics") or parcours.first("optics")
    colours = _optics(optics, path) if optics is not None else {}
    pieces = build_grid(
        [row.text for row in rows],
        cell=DEFAULT_CELL,
        colours=colours,
        row_lines=[row.line for row in rows],
        path=path,
    )
    description = root.first("description")
    return WorldSpec(
        name=path.stem,
        bounds=pieces.bounds,
        walls=pieces.walls,
        floor=pieces.floor,
        lines=pieces.lines,
        holes=pieces.holes,
        lights=pieces.lights,
        starts=pieces.starts,
        goals=pieces.goals,
        movables=pieces.movables,
        floor_colour=colours.get(" ", DEFAULT_TILE_COLOURS[" "]),
        outside_is_hole=True,
        source=str(path),
        description=re.sub(r"\s+", " ", description.text).strip() if description is not None else "",
    )


def _optics(optics: _Element, path: Path) -> dict[str, Colour]:
    """Tile → colour from `<appearance>`s: the diffuse colour, the one c't-Sim's floor sensors read
    (`World.sensGroundReflectionCross`); a material without one has Java3D's default diffuse,
    white. `<clone>` copies another tile's. Tiles without colours (textures, emissive lights)
    are left to the defaults."""
    own: dict[str, Colour] = {}
    clones: dict[str, tuple[str, int]] = {}
    for appearance in optics.all("appearance"):
        tile = appearance.attrs.get("type", "")
        if len(tile) != 1:
            raise WorldFileError(path, appearance.line, f"<appearance type={tile!r}>: the type must be one tile character")
        by_kind: dict[str, Colour] = {}
        for colour in appearance.all("color"):
            value = decode_colour(colour.text)
            if value is None:
                raise WorldFileError(path, colour.line, f"bad colour {colour.text.strip()!r}; expected #RRGGBB")
            by_kind[colour.attrs.get("type", "ambient")] = value
        if by_kind:
            own[tile] = by_kind.get("diffuse", (1.0, 1.0, 1.0))
        clone = appearance.first("clone")
        if clone is not None and clone.text.strip():
            clones[tile] = (clone.text.strip()[0], clone.line)
    resolved = dict(own)
    for tile in clones:
        seen = {tile}
        target, line = clones[tile]
        while target in clones:
            if target in seen:
                raise WorldFileError(path, line, f"<clone> loop through tile {target!r}")
            seen.add(target)
            target = clones[target][0]
        if target in own:
            resolved[tile] = own[target]
        elif target in DEFAULT_TILE_COLOURS:
            resolved[tile] = DEFAULT_TILE_COLOURS[target]
    return resolved


def decode_colour(text: str) -> Colour | None:
    """A colour as Java's Color.decode reads c't-Sim optics: `#`/`0x` hex, a leading `0` octal,
    else decimal (so the `990000` in some shipped files is 0x0F1B30, as c't-Sim shows it)."""
    t = text.strip()
    try:
        if t[:1] == "#" or t[:2].lower() == "0x":
            value = int(t[1:] if t[0] == "#" else t[2:], 16)
        elif len(t) > 1 and t[0] == "0":
            value = int(t[1:], 8)
        else:
            value = int(t, 10)
    except ValueError:
        return None
    if not 0 <= value <= 0xFFFFFF:
        return None
    return ((value >> 16) / 255, ((value >> 8) & 0xFF) / 255, (value & 0xFF) / 255)
