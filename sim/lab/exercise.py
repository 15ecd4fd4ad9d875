"""Exercises as data: one folder each, read from TOML, Markdown and two Python files.

    NN_name/
      exercise.toml     number, titles, the student's file name, time limit, tolerances,
                        public examples, ranges for hidden scenarios, hints (English and German),
                        the project modules the template imports (all the student's code sees)
      sheet.en.md       the exercise sheet, English
      sheet.de.md       the exercise sheet, German
      template.py       what the student starts from
      checker.py        check(scenario, student) -> Outcome; optionally draw(rng, index, ranges)

The shipped exercises live in `sim/lab/exercises/`; a teacher adds more in a folder of their own
(`ctsim lab --exercises DIR` or the CTSIM_LAB_EXERCISES variable) without touching ctsim's code.
"""

from __future__ import annotations

import importlib.util
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from bots.schema import Field, Problem
from bots.spec import read_toml
from sim.errors import UserError
from sim.sandbox.launch import module_file

SHIPPED = Path(__file__).resolve().parent / "exercises"
LANGUAGES = ("en", "de")
ENVIRONMENT = "CTSIM_LAB_EXERCISES"
STARTUP_WALL = 30.0
"""Wall-clock seconds a submission may spend starting its process (Python, numpy, loading its
file), over all its start-ups, besides its scenarios' time limits: a busy grading machine needs
a few seconds a start."""


class ExerciseError(UserError):
    """A mistake in an exercise folder or in choosing one (message for the user)."""


@dataclass(frozen=True)
class Scenario:
    """One case the checker runs: `params` from the examples or drawn; `seed` for any randomness
    of its own (a world's noise); `hidden` ones never show their values."""

    name: str
    params: dict[str, Any]
    hidden: bool
    seed: int
    tolerance: dict[str, float]
    out: Path | None = None
    names: dict[str, str] = field(default_factory=dict)
    """The name in other languages than English (an example's `name_de`)."""

    def __getitem__(self, key: str) -> Any:
        return self.params[key]

    def label(self, lang: str) -> str:
        """The name as a table in `lang` shows it."""
        return self.names.get(lang, self.name)


@dataclass
class Exercise:
    """An exercise folder, read. `modules`: the project modules the template imports (say
    `bots.commands`): with what they import, all of the project the student's code can see;
    `budget`: wall-clock seconds for one submission, start-ups included (None: the time limit
    of every scenario, plus `STARTUP_WALL`)."""

    folder: Path
    number: int
    title: dict[str, str]
    summary: dict[str, str]
    file: str
    time_limit: float
    hidden: int
    points: float
    tolerance: dict[str, float]
    examples: list[dict[str, Any]]
    ranges: dict[str, Any]
    hints: dict[str, dict[str, str]]
    modules: tuple[str, ...] = ()
    budget: float | None = None
    _checker: ModuleType | None = field(default=None, repr=False)

    @property
    def checker(self) -> ModuleType:
        """checker.py of the folder, loaded once."""
        if self._checker is None:
            path = self.folder / "checker.py"
            spec = importlib.util.spec_from_file_location(f"ctsim_lab_checker_{self.number}", path)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            if not callable(getattr(module, "check", None)):
                raise ExerciseError(f"{path}: defines no check(scenario, student)")
            self._checker = module
        return self._checker

    def wall(self, scenarios: int) -> float:
        """Wall-clock seconds one submission of `scenarios` scenarios may take, start-ups included."""
        return self.budget if self.budget is not None else self.time_limit * scenarios + STARTUP_WALL

    def sheet(self, lang: str) -> str:
        """The exercise sheet (Markdown) in `lang`."""
        return (self.folder / f"sheet.{lang}.md").read_text(encoding="utf-8")

    def template(self) -> str:
        return (self.folder / "template.py").read_text(encoding="utf-8")

    def hint(self, key: str, lang: str, shared: dict[str, dict[str, str]], **args: Any) -> str:
        """The hint `key` in `lang`, the exercise's own first, then the shared ones."""
        texts = self.hints.get(key) or shared.get(key) or {"en": key, "de": key}
        text = texts.get(lang) or texts["en"]
        try:
            return text.format(**args)
        except (KeyError, IndexError, ValueError):
            return text

    def scenarios(self, seed: int, out: Path | None = None) -> list[Scenario]:
        """The public examples, then `hidden` scenarios drawn from `seed`."""
        root = np.random.SeedSequence(seed)
        children = root.spawn(len(self.examples) + self.hidden)
        found = [
            Scenario(name, dict(example), False, _seed(children[i]), self.tolerance, out / slug(name) if out else None,
                     {lang: str(example[f"name_{lang}"]) for lang in LANGUAGES if f"name_{lang}" in example})
            for i, example in enumerate(self.examples)
            for name in [str(example.get("name", f"example {i + 1}"))]
        ]  # fmt: skip
        draw = getattr(self.checker, "draw", draw_ranges)
        for k in range(self.hidden):
            child = children[len(self.examples) + k]
            rng = np.random.default_rng(child)
            found.append(Scenario(f"hidden {k + 1}", draw(rng, k, self.ranges), True, _seed(child), self.tolerance, None, {"de": f"verdeckt {k + 1}"}))
        return found


def slug(name: str) -> str:
    """A scenario name as a folder name."""
    return "".join(c if c.isalnum() else "-" for c in name.lower()).strip("-") or "scenario"


def _seed(sequence: np.random.SeedSequence) -> int:
    return int(sequence.generate_state(1, np.uint32)[0])


def draw_ranges(rng: np.random.Generator, index: int, ranges: dict[str, Any]) -> dict[str, Any]:
    """One hidden scenario from the [draw] table: [low, high] uniform, a list of anything else
    one of its items, a single value itself."""
    params = {}
    for key, spec in ranges.items():
        if isinstance(spec, list) and len(spec) == 2 and all(isinstance(v, (int, float)) for v in spec):
            params[key] = float(rng.uniform(spec[0], spec[1]))
        elif isinstance(spec, list) and spec:
            params[key] = spec[int(rng.integers(len(spec)))]
        else:
            params[key] = spec
    return params


def _texts(data: dict, key: str, path: Path) -> dict[str, str]:
    value = data.get(key)
    if not (isinstance(value, dict) and all(isinstance(value.get(lang), str) for lang in LANGUAGES)):
        raise ExerciseError(f"{path}: '{key}' needs a text for each language: {key} = {{ en = \"...\", de = \"...\" }}")
    return value


def load_exercise(folder: str | Path) -> Exercise:
    """Read an exercise folder; mistakes are reported as `file: problem`."""
    folder = Path(folder)
    path = folder / "exercise.toml"
    data = read_toml(path, ExerciseError)
    for required in ("number", "file"):
        if required not in data:
            raise ExerciseError(f"{path}: missing key '{required}'")
    for name in ("template.py", "checker.py", *(f"sheet.{lang}.md" for lang in LANGUAGES)):
        if not (folder / name).is_file():
            raise ExerciseError(f"{folder}: missing {name}")
    hints = data.get("hints", {})
    for key in hints:
        _texts(hints, key, path)
    modules = data.get("modules", [])
    if not (isinstance(modules, list) and all(isinstance(m, str) for m in modules)):
        raise ExerciseError(f"{path}: 'modules' must be a list of module names, such as [\"bots.commands\"]")
    for name in modules:
        if module_file(name) is None:
            raise ExerciseError(f"{path}: modules: {name!r} is no module of ctsim (sim.* or bots.*)")
    value = _checked(data, path)
    return Exercise(
        folder=folder,
        number=value("number"),
        title=_texts(data, "title", path),
        summary=_texts(data, "summary", path),
        file=value("file"),
        time_limit=value("time_limit", 5.0),
        hidden=value("hidden", 0),
        points=value("points", 10.0),
        tolerance={k: float(v) for k, v in data.get("tolerance", {}).items()},
        examples=list(data.get("example", [])),
        ranges=dict(data.get("draw", {})),
        hints=hints,
        modules=tuple(modules),
        budget=value("budget", None),
    )


FIELDS = {"number": Field("integer", "", 1, 9999), "file": Field("text"), "time_limit": Field("number", "s", 0.0, 3600.0, above=True),
          "hidden": Field("integer", "scenarios", 0, 100_000), "points": Field("number", "points", 0.0, 1e6),
          "budget": Field("number", "s", 0.0, 86_400.0, above=True)}
"""The scalar keys of exercise.toml, checked as every ctsim file's (`bots.schema.Field`)."""


def _checked(data: dict, path: Path):
    """`value(key, default)`: the key's value checked against FIELDS, ExerciseError naming file and key."""

    def value(key: str, default=None):
        if key not in data:
            return default
        try:
            return FIELDS[key].check(data[key])
        except Problem as problem:
            raise ExerciseError(f"{path}: {key}: {problem.message}") from None

    return value


def folders(extra: list[str | Path] | None = None) -> list[Path]:
    """Where exercises are looked for: the shipped ones, CTSIM_LAB_EXERCISES, then `extra`."""
    places = [SHIPPED] + [Path(p) for p in os.environ.get(ENVIRONMENT, "").split(os.pathsep) if p] + [Path(p) for p in extra or ()]
    for place in places:
        if not place.is_dir():
            raise ExerciseError(f"{place}: no such exercise folder")
    return places


def exercises(extra: list[str | Path] | None = None) -> dict[int, Exercise]:
    """Every exercise by number, sorted; two folders with the same number are an error."""
    found: dict[int, Exercise] = {}
    for place in folders(extra):
        for toml in sorted(place.glob("*/exercise.toml")):
            exercise = load_exercise(toml.parent)
            if exercise.number in found:
                raise ExerciseError(f"{toml.parent} and {found[exercise.number].folder} both are exercise {exercise.number}")
            found[exercise.number] = exercise
    return dict(sorted(found.items()))


def exercise(number: int, extra: list[str | Path] | None = None) -> Exercise:
    """Exercise `number`, or an error listing the ones there are."""
    known = exercises(extra)
    if number not in known:
        raise ExerciseError(f"no exercise {number} (there are: {', '.join(map(str, known)) or 'none'}; see `ctsim lab list`)")
    return known[number]


def shared_hints() -> dict[str, dict[str, str]]:
    """The hints every exercise shares (student code that raises, hangs, returns nonsense...)."""
    return tomllib.loads((Path(__file__).resolve().parent / "hints.toml").read_text(encoding="utf-8"))
