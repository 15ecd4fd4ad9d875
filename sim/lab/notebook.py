"""An exercise as a Jupyter notebook, and a notebook handed in as the file the grader reads.

`ctsim lab start N DIR --notebook` writes `exerciseN.ipynb`: the sheet as Markdown cells (one per
section), the template as one code cell tagged `solution` whose first line `%%writefile FILE`
makes running it write the very file `ctsim lab check` grades, and a last cell that checks that
file and prints the table with its hints. `ctsim lab check N exerciseN.ipynb` takes the tagged
cell's code (the magic line dropped) into a file of the exercise's name in a fresh folder and
grades that file, in the same sandbox and with the same hints as a `.py` handed in.

Notebooks are plain JSON (nbformat 4): writing and reading one needs no Jupyter package.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bots.schema import read_bytes
from sim import sanitize
from sim.errors import UserError
from sim.lab.exercise import Exercise, ExerciseError
from sim.out_files import write_text

SOLUTION_TAG = "solution"
"""The tag of the code cell that holds the student's solution."""
SUFFIX = ".ipynb"
LARGEST = 20 << 20
"""Bytes of the largest notebook read (an exercise's is a few kilobytes; outputs may add images)."""


def _cell(kind: str, text: str, tags: tuple[str, ...] = ()) -> dict[str, Any]:
    cell: dict[str, Any] = {"cell_type": kind, "metadata": {"tags": list(tags)} if tags else {}, "source": text.splitlines(keepends=True)}
    if kind == "code":
        cell |= {"execution_count": None, "outputs": []}
    return cell


def _sections(markdown: str) -> list[str]:
    """The sheet split before each heading: one Markdown cell per section."""
    parts: list[list[str]] = [[]]
    for line in markdown.splitlines(keepends=True):
        if line.startswith("#") and any(part.strip() for part in parts[-1]):
            parts.append([])
        parts[-1].append(line)
    return ["".join(part).strip("\n") for part in parts if "".join(part).strip()]


def notebook(exercise: Exercise, lang: str = "en", extra: tuple[str, ...] | list[str] = ()) -> dict[str, Any]:
    """The exercise as an nbformat-4 notebook (a JSON-ready dict)."""
    how = {
        "en": f"Write your solution in the next cell and run it: its first line saves it as `{exercise.file}`, the file "
        f"that is graded. Then run the check below (or `ctsim lab check {exercise.number} {exercise.file}` in a terminal).",
        "de": f"Schreiben Sie Ihre Lösung in die nächste Zelle und führen Sie sie aus: ihre erste Zeile speichert sie als "
        f"`{exercise.file}`, die Datei, die bewertet wird. Dann führen Sie die Prüfung darunter aus (oder "
        f"`ctsim lab check {exercise.number} {exercise.file}` im Terminal).",
    }[lang]
    options = f", exercises={list(extra)!r}" if extra else ""
    cells = [
        *(_cell("markdown", section) for section in _sections(exercise.sheet(lang))),
        _cell("markdown", how),
        _cell("code", f"%%writefile {exercise.file}\n{exercise.template().rstrip()}\n", (SOLUTION_TAG,)),
        _cell("code", f"from sim.lab.notebook import check\n\ncheck({exercise.number}, lang={lang!r}{options})\n"),
    ]
    kernel = {"display_name": "Python 3", "language": "python", "name": "python3"}
    return {"cells": cells, "metadata": {"kernelspec": kernel, "language_info": {"name": "python"}}, "nbformat": 4, "nbformat_minor": 5}


def write_notebook(exercise: Exercise, folder: Path, lang: str = "en", extra: tuple[str, ...] | list[str] = ()) -> Path:
    """exerciseN.ipynb in `folder` (kept if it exists: it may hold a student's work)."""
    path = folder / f"exercise{exercise.number}{SUFFIX}"
    if not os.path.lexists(path):
        document = notebook(exercise, lang, extra)
        for i, cell in enumerate(document["cells"]):  # nbformat 4.5 wants an id per cell
            cell["id"] = f"ctsim-{exercise.number}-{i}"
        write_text(path, json.dumps(document, indent=1, ensure_ascii=False) + "\n")
    return path


def solution_source(path: Path) -> str:
    """The code of the notebook's cell tagged `solution`, its magic lines (`%%writefile`) dropped.
    The one boundary of reading a student's notebook: whatever reading it raises (bad JSON, a
    number past Python's digit limit, a lone surrogate, a pipe for a file) is an ExerciseError
    naming the file, that student's failure to load and never the class's."""
    try:
        return _solution(path)
    except UserError as err:
        raise ExerciseError(str(err)) from None
    except Exception as err:  # noqa: BLE001 (every failure of reading the student's own file is that file's)
        raise ExerciseError(f"{path}: not a notebook ctsim can read ({type(err).__name__}: {sanitize.name(str(err), 200)})") from None


def _solution(path: Path) -> str:
    try:
        document = json.loads(read_bytes(path, most=LARGEST).decode("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ExerciseError(f"{path}: not a notebook (not JSON: {sanitize.name(str(err), 200)})") from None
    except RecursionError:
        raise ExerciseError(f"{path}: not a notebook (its JSON is nested too deep to read)") from None
    cells = document.get("cells") if isinstance(document, dict) else None
    if not isinstance(cells, list):
        raise ExerciseError(f"{path}: not a notebook (no cells)")
    tagged = [c for c in cells if isinstance(c, dict) and c.get("cell_type") == "code" and SOLUTION_TAG in _tags(c)]
    if len(tagged) != 1:
        raise ExerciseError(f"{path}: {len(tagged)} code cells tagged '{SOLUTION_TAG}'; the solution must be in exactly one (the cell `ctsim lab start --notebook` wrote)")
    source = tagged[0].get("source", "")
    if not (isinstance(source, str) or (isinstance(source, list) and all(isinstance(line, str) for line in source))):
        raise ExerciseError(f"{path}: the '{SOLUTION_TAG}' cell's source is not text (nbformat: a string or a list of strings)")
    text = "".join(line for line in "".join(source).splitlines(keepends=True) if not line.lstrip().startswith("%"))
    text.encode("utf-8")  # (a lone surrogate, written as \\ud800 in the JSON, is no text of a file: refused here)
    return text


def _tags(cell: dict[str, Any]) -> list[Any]:
    """A cell's tags; none where its metadata is not what nbformat says it is."""
    metadata = cell.get("metadata")
    tags = metadata.get("tags") if isinstance(metadata, dict) else None
    return tags if isinstance(tags, list) else []


@contextmanager
def submission(path: Path, exercise: Exercise) -> Iterator[Path]:
    """The file to grade: `path` itself, or for a notebook its solution written as the
    exercise's file in a folder of its own (removed afterwards)."""
    if path.suffix != SUFFIX:
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="ctsim-notebook-") as folder:
        file = Path(folder) / exercise.file
        file.write_text(solution_source(path), encoding="utf-8")
        yield file


def check(number: int, lang: str = "en", exercises: list[str] | tuple[str, ...] = (), out: str | Path | None = None, degraded: bool = False) -> bool:
    """The notebook's check cell: grade the file the solution cell wrote as `ctsim lab check`
    does (the same sandbox, table and hints, and `out` likewise), show the figures; whether every
    scenario passed."""
    from sim.lab.checking import check_and_print
    from sim.lab.exercise import exercise

    ex = exercise(number, list(exercises))
    file = Path(ex.file)
    if not file.is_file():
        print(f"{file} is not written yet: run the solution cell (its first line is %%writefile {file}) first")
        return False
    report = check_and_print(ex, file, file, lang, None if out is None else Path(out), degraded)
    _show([path for path in report.artifacts if path.suffix == ".png"])
    return report.passed


def _show(pictures: list[Path]) -> None:
    """The check's figures inline (in IPython; elsewhere the table names nothing more)."""
    try:
        from IPython import get_ipython
        from IPython.display import Image, display
    except ImportError:
        return
    if get_ipython() is None:
        return
    for picture in pictures:
        display(Image(filename=str(picture)))
