"""sim.sanitize: text from a submission cannot act where it is written (terminal, CSV, JSON,
XML), and a long field is cut saying how long it was."""

from __future__ import annotations

import csv
import io
import json
import unicodedata
from xml.etree import ElementTree as ET

from hypothesis import example, given
from hypothesis import strategies as st

from sim import sanitize


def test_escape_sequences_and_controls_become_visible_text() -> None:
    assert sanitize.terminal("a\x1b[2Jb\x07\n") == "a\\x1b[2Jb\\x07\n"
    assert sanitize.name("alice\n 10/10  mallory") == "alice\\x0a 10/10  mallory"
    assert sanitize.name("evil\u202etxt.py") == "evil\\u202etxt.py"
    assert sanitize.name("\x9b31m") == "\\x9b31m"  # the one-byte CSI of C1


def test_cells_that_start_like_a_formula_are_quoted_and_others_kept() -> None:
    for formula in ("=1+1", "+A1", "-2+3", "@SUM(A1)", "\uff1dcmd"):
        assert sanitize.csv_cell(formula).startswith("'"), formula
    assert sanitize.csv_cell("alice") == "alice"
    assert sanitize.csv_cell("a\nb") == "a\\x0ab" and sanitize.csv_cell("\tx") == "\\x09x"  # a tab is escaped, so it starts nothing


def test_long_fields_are_cut_with_their_length_said() -> None:
    cut = sanitize.truncate("x" * 600_000, 100)
    assert cut.startswith("x" * 100) and "600000 characters" in cut and len(cut) < 150
    assert sanitize.truncate("short", 100) == "short"


@given(st.text())
def test_any_text_is_one_safe_line_and_a_plain_csv_cell(text: str) -> None:
    line = sanitize.name(text)
    assert not any(unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp", "Cs") for c in line)  # nothing a terminal acts on
    cell = sanitize.csv_cell(text)
    buffer = io.StringIO()
    csv.writer(buffer).writerow([cell])
    assert next(csv.reader(io.StringIO(buffer.getvalue()))) == [cell]
    assert not cell.startswith(sanitize.FORMULA_STARTS[:4])


@given(st.text())
@example("\r\n")
def test_any_text_goes_into_xml_and_strict_json(text: str) -> None:
    """The text reads back as written, but for XML's own end-of-line rule (a parser reads CR LF
    and a lone CR as LF, XML 1.0 section 2.11; hypothesis once drew CR LF)."""
    element = ET.Element("case", name=sanitize.xml_text(text))
    element.text = sanitize.xml_text(text)
    back = ET.fromstring(ET.tostring(element, encoding="unicode"))
    assert back.text in (element.text, None) or back.text == element.text.replace("\r\n", "\n").replace("\r", "\n")
    encoded = json.dumps(sanitize.json_text(text), ensure_ascii=False)
    encoded.encode("utf-8")  # no lone surrogate: strict readers accept it
    assert "\x1b" not in json.loads(encoded)


SCREEN_ACTING = ("Cc", "Cf", "Zl", "Zp", "Cs")
"""Character classes that act on a reader's screen or are no text: controls, format characters
(the right-to-left override U+202E among them), line and paragraph separators, lone surrogates."""


@given(st.text())
def test_csv_junit_and_json_texts_are_sanitised_alike(text: str) -> None:
    for safe in (sanitize.csv_cell(text), sanitize.xml_text(text), sanitize.json_text(text)):
        assert not any(unicodedata.category(c) in SCREEN_ACTING and c not in "\t\n\r" for c in safe), safe
