"""A submission that is no solution yet, told before anything runs: the template's placeholder (a
function or method whose body is only `raise NotImplementedError(...)`) still in place, or the
name the template asks for nowhere in the file. Running the scenarios would say only that, in
every row, after seconds of runs and replays (exercise 3 runs a robot and replays 30 typical
mistakes for each scenario before it asks the student's code anything).

The file is read as text and parsed, never run. Whatever cannot be told for sure from the text
(a name made by an import or an assignment, a file that does not parse) is left to the scenarios.
"""

from __future__ import annotations

import ast
import io
import os
import stat
import tokenize
from dataclasses import dataclass
from pathlib import Path

LARGEST = 1_000_000
"""Bytes of a student's file read here at most (a larger one is left to the sandbox's limits)."""


@dataclass(frozen=True)
class Gap:
    """What the file lacks: `kind` "placeholder" (the template's `raise NotImplementedError` is still
    `name`'s body) or "undefined" (no `name` anywhere in the file)."""

    kind: str
    name: str


def placeholders(source: str) -> list[str]:
    """The template's functions and methods ("turn", "Odometry.update") that only raise NotImplementedError."""
    return [name for name, node in _definitions(ast.parse(source)).items() if _only_raises(node)]


def gap(template: str, path: Path) -> Gap | None:
    """What keeps the file at `path` from being a solution of the exercise whose template is
    `template` (the first placeholder the file still has or lacks), or None: the scenarios tell."""
    try:
        source = _read(path)
        if source is None:
            return None
        tree = ast.parse(source)
        words = _identifiers(source)
        wanted = placeholders(template)
    except (OSError, UnicodeDecodeError, SyntaxError, ValueError, RecursionError, MemoryError, tokenize.TokenError):
        return None  # (the sandbox says what is wrong with a file that does not load; a teacher's template that does not parse has no placeholder)
    defined = _definitions(tree)
    star = any(isinstance(node, ast.alias) and node.name == "*" for node in ast.walk(tree))
    for name in wanted:
        if name.split(".")[0] not in words and not star:
            return Gap("undefined", name.split(".")[0])
        node = defined.get(name)
        if node is not None and _only_raises(node) and not _rebound(tree, name):
            return Gap("placeholder", name)
    return None


def _read(path: Path) -> str | None:
    """The file's text, or None for anything but a regular file of at most LARGEST bytes (a pipe
    is not waited for)."""
    descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(descriptor, "rb") as file:
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode) or info.st_size > LARGEST:
            return None
        return file.read(LARGEST + 1).decode("utf-8")


def _definitions(tree: ast.Module) -> dict[str, ast.FunctionDef]:
    """Top-level functions and methods of top-level classes by name, the last definition of each
    (the one Python keeps)."""
    found: dict[str, ast.FunctionDef] = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            found[node.name] = node
        elif isinstance(node, ast.ClassDef):
            found = {k: v for k, v in found.items() if not k.startswith(f"{node.name}.")}  # (a class defined again replaces the first)
            for item in node.body:
                if isinstance(item, ast.FunctionDef | ast.AsyncFunctionDef):
                    found[f"{node.name}.{item.name}"] = item
    return found


def _only_raises(function: ast.FunctionDef) -> bool:
    """Whether the body is a docstring at most and `raise NotImplementedError` (called or not)."""
    body = function.body[1:] if ast.get_docstring(function) is not None else function.body
    if len(body) != 1 or not isinstance(body[0], ast.Raise) or body[0].exc is None:
        return False
    raised = body[0].exc.func if isinstance(body[0].exc, ast.Call) else body[0].exc
    return isinstance(raised, ast.Name) and raised.id == "NotImplementedError"


def _rebound(tree: ast.Module, name: str) -> bool:
    """Whether anything but its `def` (re)binds `name` at the top level: a later import or
    assignment of the function or class, or of the method on its class (`Odometry.update = ...`)."""
    top, _, method = name.partition(".")
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            continue
        for sub in ast.walk(node):
            if isinstance(sub, ast.alias) and (sub.asname or sub.name).split(".")[0] in (top, "*"):
                return True
            if isinstance(sub, ast.Name) and sub.id == top and isinstance(sub.ctx, ast.Store):
                return True
            if method and isinstance(sub, ast.Attribute) and sub.attr == method and isinstance(sub.ctx, ast.Store):
                return True
    return False


def _identifiers(source: str) -> set[str]:
    """Every name and word of a string in the file (a name the file mentions nowhere, and imports
    no `*` that could bring it, is missing for sure; one it mentions may be made in ways the text
    does not show)."""
    words: set[str] = set()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.NAME:
            words.add(token.string)
        elif token.type == tokenize.STRING:
            words.update(token.string.replace(".", " ").replace("'", " ").replace('"', " ").split())
    return words
