"""Importer for c't-Sim parcours XML: `<world><description/><parcours><line>…</line>…</parcours>
<optics><appearance type="c">…</appearance></optics></world>` (ctsim-reference.md §3).

Read by defusedxml's SAX parser, which refuses entity declarations (the "billion laughs"), and
never fetches the DOCTYPE's `parcours.dtd` or any other external resource (SAX's external-entity
features off); its locator gives each
element's line, so an error names the line of the offending `<line>`. Elements may nest at most
MAX_DEPTH deep and the file is a regular one of at most `bots.schema.MAX_BYTES`.
"""

from __future__ import annotations

import difflib
import io
import re
import xml.sax
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from defusedxml import DefusedXmlException
from defusedxml.expatreader import DefusedExpatParser

from bots.schema import read_bytes
from sim.world.spec import Colour, WorldFileError, WorldSpec

from .grid import DEFAULT_CELL, DEFAULT_TILE_COLOURS, LINE_HEIGHT, build_grid

MAX_DEPTH = 16
"""Deepest element nesting a parcours may have (c't-Sim's own: 4)."""


@dataclass
class _Element:
    tag: str
    attrs: dict[str, str]
    line: int
    chunks: list[str] = field(default_factory=list)
    children: list[_Element] = field(default_factory=list)

    @property
    def text(self) -> str:
        """The element's text (kept in pieces as the parser delivers it, joined once)."""
        return "".join(self.chunks)

    def all(self, tag: str) -> list[_Element]:
        return [e for e in self.children if e.tag == tag]

    def first(self, tag: str) -> _Element | None:
        return next(iter(self.all(tag)), None)


class _TreeBuilder(xml.sax.handler.ContentHandler):
    """A minimal element tree with each element's start line."""

    def __init__(self, path: Path):
        super().__init__()
        self.path = path
        self.stack: list[_Element] = [_Element("", {}, 0)]
        self.locator: Any = None

    def setDocumentLocator(self, locator: Any) -> None:  # noqa: N802 (SAX's name)
        self.locator = locator

    def line(self) -> int | None:
        return self.locator.getLineNumber() if self.locator is not None else None

    def startElement(self, name: str, attrs: Any) -> None:  # noqa: N802
        if len(self.stack) > MAX_DEPTH:
            raise WorldFileError(self.path, self.line(), f"elements nested deeper than {MAX_DEPTH} levels")
        element = _Element(name, dict(attrs), self.line() or 0)
        self.stack[-1].children.append(element)
        self.stack.append(element)

    def endElement(self, name: str) -> None:  # noqa: N802
        self.stack.pop()

    def characters(self, content: str) -> None:
        self.stack[-1].chunks.append(content)


def _parse_xml(data: bytes, path: Path) -> _Element:
    """The element tree; XML errors and refused constructs become WorldFileError."""
    builder = _TreeBuilder(path)
    parser = DefusedExpatParser(forbid_dtd=False, forbid_entities=True, forbid_external=False)  # (a DOCTYPE naming parcours.dtd is fine:
    parser.setFeature(xml.sax.handler.feature_external_ges, False)                              # the features keep it from being read)
    parser.setFeature(xml.sax.handler.feature_external_pes, False)
    parser.setContentHandler(builder)
    try:
        parser.parse(io.BytesIO(data))
    except xml.sax.SAXParseException as e:
        raise WorldFileError(path, e.getLineNumber(), f"XML error: {e.getMessage()}") from None
    except DefusedXmlException as e:
        raise WorldFileError(path, builder.line(), f"XML refused: {type(e).__name__} ({e}); a parcours needs no entities") from None
    if not builder.stack[0].children:
        raise WorldFileError(path, None, "XML error: no element found")
    return builder.stack[0].children[0]


def load_parcours(path: Path, pillars: str = "cell") -> WorldSpec:
    """Load a c't-Sim parcours file; everything outside the map is a hole, as in c't-Sim.
    `pillars`: how lamp pillars stand (`build_grid`)."""
    data = read_bytes(path, WorldFileError)
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
        pillars=pillars,
    )
    description = root.first("description")
    notes = tuple(_unknown_tags(root))
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
        scene=pieces.scene,
        floor_colour=colours.get(" ", DEFAULT_TILE_COLOURS[" "]),
        outside_is_hole=True,
        line_height=LINE_HEIGHT,
        source=str(path),
        description=re.sub(r"\s+", " ", description.text).strip() if description is not None else "",
        notes=notes,
    )


KNOWN_TAGS = {"world": ("description", "parcours", "optics"), "parcours": ("line", "optics"), "optics": ("appearance",),
              "appearance": ("description", "color", "clone", "texture")}
"""The elements c't-Sim reads inside each element (its parcours.dtd): anything else is ignored,
and said (a misspelt `<line>` would drop a row of the map)."""


def _unknown_tags(root: _Element) -> Iterator[str]:
    """A note per element c't-Sim would not read, with its line and the closest known tag."""
    todo = [root]
    while todo:
        element = todo.pop()
        known = KNOWN_TAGS.get(element.tag)
        if known is None:
            continue
        for child in element.children:
            if child.tag in known:
                todo.append(child)
                continue
            close = difflib.get_close_matches(child.tag, known, n=1)
            hint = f"; did you mean <{close[0]}>?" if close else f" (known there: {', '.join(f'<{t}>' for t in known)})"
            yield f"line {child.line}: unknown tag <{child.tag}> inside <{element.tag}>, ignored{hint}"


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
