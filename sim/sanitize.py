"""Text from outside (a student's file name, what untrusted code printed or answered, a file's
contents) made safe for where it goes: a terminal, a CSV cell, JSON, XML.

Each function takes any string and returns one that cannot act in its target: no escape
sequence reaches a terminal, no line break forges a line, no cell starts a spreadsheet formula,
no character XML 1.0 cannot hold is written. Long texts are cut with their length said, so that
one forged 600 kB field cannot fill a report. Standard library only.
"""

from __future__ import annotations

import json
import re
import unicodedata
from typing import Any

LONG = 2000
"""Characters a field keeps by default before it is cut (`truncate`)."""
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r", "\n", "\uff1d", "\uff0b", "\uff0d", "\uff20")
"""First characters that make a spreadsheet read a cell as a formula (fullwidth forms too: some
spreadsheets fold them)."""


def truncate(text: str, limit: int = LONG) -> str:
    """`text` cut to at most `limit` characters plus a note of how long it was."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}[... cut: {len(text)} characters in all]"


def _unsafe(c: str, keep: str) -> bool:
    """A character that could act on a terminal or hide text: C0 and C1 controls, DEL, and the
    format characters (bidirectional overrides, zero-width ones), unless in `keep`."""
    return c not in keep and (c < " " or "\x7f" <= c < "\xa0" or unicodedata.category(c) in ("Cf", "Zl", "Zp", "Cs"))


def _visible(c: str) -> str:
    code = ord(c)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def escape(text: str, keep: str = "") -> str:
    """Every unsafe character of `text` (but those in `keep`) as a visible escape: \\x1b, \\u202e."""
    return "".join(_visible(c) if _unsafe(c, keep) else c for c in text)


def terminal(text: str, limit: int = LONG, lines: bool = True) -> str:
    """`text` safe to print: escape sequences and control characters shown as escapes; line
    breaks and tabs kept when `lines` (a block of output), escaped too when not (a name on one
    line, so that a newline cannot forge another line); cut at `limit`."""
    return escape(truncate(text, limit), "\n\t" if lines else "")


_ASCII_CONTROLS = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
"""The unsafe characters of an ASCII text that `Terminal` escapes (most of what it gets has none)."""


class Terminal:
    """A text stream (the command line's stderr) that writes through `stream` with every unsafe
    character escaped (`escape`; line breaks, tabs and carriage returns kept: a progress bar
    redraws its line): what libraries print there (warnings of numba, pyarrow or Dask, log
    records, a traceback quoting a file's name) gets what ctsim's own messages get. Whatever else
    is asked of it, `stream` answers."""

    def __init__(self, stream: Any):
        self.stream = stream

    def write(self, text: str) -> int:
        self.stream.write(text if text.isascii() and not _ASCII_CONTROLS.search(text) else escape(text, "\n\t\r"))
        return len(text)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, key: str) -> Any:
        return getattr(self.stream, key)


def name(text: str, limit: int = 200) -> str:
    """A name (file, folder, scenario) for one line of a terminal, table or report."""
    return terminal(text, limit, lines=False)


def csv_cell(text: str, limit: int = LONG) -> str:
    """`text` for a CSV cell: one line, no controls, and one that starts like a formula
    (= + - @, tab, return) gets a leading ' so that a spreadsheet shows it as text."""
    text = escape(truncate(text, limit))
    return f"'{text}" if text.startswith(FORMULA_STARTS) else text


def xml_text(text: str, limit: int = LONG) -> str:
    """`text` for XML 1.0 content or an attribute: the characters XML cannot hold (controls,
    lone surrogates, U+FFFE/U+FFFF) and those that would act on a reader's screen (bidirectional
    overrides, zero-width ones: as in a terminal, CSV or JSON) as visible escapes, tabs and line
    breaks kept; cut at `limit`. The XML writer escapes < > & and quotes itself."""
    def allowed(c: str) -> bool:
        return c in "\t\n\r" or ("\x20" <= c <= "\ud7ff" or "\ue000" <= c <= "\ufffd" or c >= "\U00010000") and not _unsafe(c, "")

    return "".join(c if allowed(c) else _visible(c) for c in truncate(text, limit))


def json_text(text: str, limit: int = LONG) -> str:
    """`text` for a JSON string read by other tools (and shown in browsers): controls and lone
    surrogates escaped visibly (json.dumps would write a lone surrogate that strict readers
    refuse), cut at `limit`."""
    return terminal(text, limit)


def json_dumps(value: object, **kwargs: object) -> str:
    """`value` as JSON that strict readers accept: NaN and infinities refused (ValueError)."""
    return json.dumps(value, allow_nan=False, **kwargs)
