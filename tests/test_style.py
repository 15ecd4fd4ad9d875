"""The house rules hold for the whole tree: pyproject.toml's [tool.ruff] (ruff's own file:line:
messages) and the rules of docs/architecture.md that ruff cannot see (module length, compiled
functions' parameters, how a run's ending is decided, the step's one home, pinned private names)."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _ruff() -> list[str] | None:
    """ruff beside this Python (the test extra installs it), else on the path."""
    beside = Path(sys.executable).with_name("ruff")
    if beside.is_file():
        return [str(beside)]
    found = shutil.which("ruff")
    return [found] if found else None


def test_the_code_keeps_the_house_rules():
    ruff = _ruff()
    if ruff is None:
        pytest.skip("ruff is not installed (pip install -e '.[test]' brings it)")
    done = subprocess.run([*ruff, "check", "--no-cache", "--output-format", "concise", "."], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


# --- the rules ruff cannot see (issue #46), each a test that names the file and line that breaks it ---

SOURCES = sorted(p for package in ("sim", "bots") for p in (ROOT / package).rglob("*.py"))
LONGEST = 600
"""Lines a module of sim/ or bots/ may have: past it, it holds more than one job."""
LONG_ON_PURPOSE = {
    "sim/kinematics/chassis.py": "the kinematics of any wheeled chassis, Köb's thesis in one place with its equation numbers "
    "(constraints, mobility, ICR, inverse and forward kinematics), read beside the thesis",
}
MOST_PARAMETERS = 8
"""Parameters a compiled function may take: more are a table or a group that wants a name (`sim.world.layout`)."""


def _relative(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _trees():
    for path in SOURCES:
        yield _relative(path), ast.parse(path.read_text(encoding="utf-8"), str(path))


def test_no_module_is_longer_than_its_one_job():
    long = [f"{_relative(p)}: {n} lines" for p in SOURCES if (n := len(p.read_text(encoding="utf-8").splitlines())) > LONGEST and _relative(p) not in LONG_ON_PURPOSE]
    assert not long, f"over {LONGEST} lines: " + "; ".join(long)


def test_a_compiled_function_takes_a_few_grouped_parameters():
    wide = []
    for rel, tree in _trees():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and any("njit" in ast.unparse(d) or "numba" in ast.unparse(d) for d in node.decorator_list):
                count = len(node.args.posonlyargs) + len(node.args.args) + len(node.args.kwonlyargs)
                if count > MOST_PARAMETERS:
                    wide.append(f"{rel}:{node.lineno}: {node.name} takes {count}")
    assert not wide, f"more than {MOST_PARAMETERS} parameters: " + "; ".join(wide)


def test_how_a_run_ended_is_decided_by_its_ending_not_its_spelling():
    """`Ending`'s values appear as strings only in sim/run/: elsewhere a comparison with a run's
    reason (or a mapping looked up by it) uses the enum or asks its properties."""
    from sim.run.ending import Ending

    values = {e.value for e in Ending}
    spelled = []
    for rel, tree in _trees():
        if rel.startswith("sim/run/"):
            continue
        for node in ast.walk(tree):
            strings = []
            if isinstance(node, ast.Compare) and "reason" in ast.unparse(node):
                strings = [n for part in (node.left, *node.comparators) for n in ast.walk(part) if isinstance(n, ast.Constant)]
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and isinstance(node.func.value, ast.Dict) and "reason" in ast.unparse(node.args):
                strings = [k for k in node.func.value.keys if isinstance(k, ast.Constant)]  # {"error": ...}.get(result.reason)
            spelled += [f"{rel}:{s.lineno}: {s.value!r}" for s in strings if isinstance(s.value, str) and s.value in values]
    assert not spelled, "an Ending spelled as a string: " + "; ".join(spelled)


def test_the_default_step_has_one_home():
    """0.01 as a step (a name or keyword with dt or step in it) only in sim/kinematics/step.py."""
    found = []
    for rel, tree in _trees():
        if rel == "sim/kinematics/step.py":
            continue
        for node in ast.walk(tree):
            pairs = []
            if isinstance(node, ast.Assign):
                pairs = [(ast.unparse(t), node.value) for t in node.targets]
            elif isinstance(node, ast.keyword) and node.arg:
                pairs = [(node.arg, node.value)]
            elif isinstance(node, ast.Call) and len(node.args) == 2 and isinstance(node.args[0], ast.Constant):
                pairs = [(str(node.args[0].value), node.args[1])]  # .get("dt", 0.01)
            for name, value in pairs:
                if isinstance(value, ast.Constant) and value.value == 0.01 and ("dt" in name.lower() or "step" in name.lower()):
                    found.append(f"{rel}:{node.lineno}: {name} = 0.01")
    assert not found, "a step of 0.01 outside sim/kinematics/step.py (use DEFAULT_DT): " + "; ".join(found)


def test_a_module_reading_a_librarys_private_names_states_the_pinned_version():
    """An import from a library's private module (`from pymunk._chipmunk import ...`) depends on
    that version: the module names the version it reads and pyproject.toml pins it."""
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    unpinned = []
    for rel, tree in _trees():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and any(part.startswith("_") for part in node.module.split(".")[1:]):
                library = node.module.split(".")[0]
                pin = re.search(rf'"{library}>=([0-9.]+),<([0-9.]+)"', pyproject)
                text = (ROOT / rel).read_text(encoding="utf-8")
                if pin is None or f"{library} {pin.group(1)}" not in text:
                    unpinned.append(f"{rel}:{node.lineno}: {node.module} (pyproject.toml pins {library} as {pin.group(0) if pin else 'nothing'})")
    assert not unpinned, "private names of an unpinned library: " + "; ".join(unpinned)


def test_a_run_folder_s_file_names_have_one_home():
    """summary.json, run.rrd and the other files of a run folder are named (as strings, docstrings
    aside) only in sim/analysis/run_folder.py; writers and readers ask `RunFolder` for the paths."""
    from sim.analysis import run_folder

    names = {path.name for path in run_folder.RunFolder(Path(".")).fixed}
    found = []
    for rel, tree in _trees():
        if rel == "sim/analysis/run_folder.py":
            continue
        docstrings = {id(body[0].value) for node in ast.walk(tree) if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef)
                      for body in [node.body] if body and isinstance(body[0], ast.Expr)}  # fmt: skip
        found += [f"{rel}:{n.lineno}: {n.value!r}" for n in ast.walk(tree) if isinstance(n, ast.Constant) and n.value in names and id(n) not in docstrings]
    assert not found, "a run folder's file named outside run_folder.py (use RunFolder): " + "; ".join(found)


OTHER_MEANINGS = {
    # where a kind's name is also a word for something else (the sensor registry's kinds are
    # `Readings` fields; these are not): file and the words, with what they name there
    "sim/kinematics/__init__.py": ({"mouse_counts"}, "the core's function of that name, in __all__"),
    "bots/spec.py": ({"line", "border", "light"}, "the robot file's sections (the registry's `section`s: tests/test_sensor_kinds.py holds them equal)"),
    "bots/behaviours/floor.py": ({"line", "border"}, "the robot-file section of sensors a behaviour needs"),
    "bots/behaviours/walls.py": ({"line"}, "the robot-file section of sensors a behaviour needs"),
    "bots/behaviours/ocp_path.py": ({"line"}, "the OCP's steering-angle convention"),
    "sim/kinematics/ocp.py": ({"line"}, "the OCP's steering-angle convention"),
    "sim/kinematics/chassis.py": ({"line"}, "an ICR locus on a line"),
    "sim/experiments/gym.py": ({"line"}, "the line-following task (and the line sensors its reward watches)"),
    "sim/sandbox/box.py": ({"line"}, "the line number of a user's error"),
    "sim/sandbox/guest.py": ({"line"}, "the line number of a user's error"),
    "sim/sandbox/reply.py": ({"line"}, "the line number of a user's error"),
    "sim/views/figures.py": ({"line", "light"}, "a world's floor line and lamps in a figure's legend"),
    "sim/views/map_image.py": ({"light"}, "a world's lamp drawn on the map"),
    "sim/world/files/parcours.py": ({"line"}, "c't-Sim's parcours character of a floor line"),
    "sim/world/files/toml_format.py": ({"line", "light"}, "a world file's tables of floor lines and lamps"),
    "sim/world/spec.py": ({"steering"}, "a wheel fault's kind"),
    "sim/world/chassis_drive.py": ({"steering"}, "a wheel fault's kind"),
}


def test_sensor_kinds_are_spelled_only_in_the_registry():
    """A sensor kind's name (a `Readings` field of `bots.sensor_kinds`) appears as a string only in
    the registry (docstrings aside): every other part iterates over it or asks a row's column, so
    a new kind is one row. OTHER_MEANINGS lists where the same word names something else."""
    from bots.sensor_kinds import KINDS

    kinds = {kind.field for kind in KINDS}
    spelled = []
    for rel, tree in _trees():
        if rel == "bots/sensor_kinds.py":
            continue
        allowed = OTHER_MEANINGS.get(rel, (set(), ""))[0]
        docstrings = {id(node.body[0].value) for node in ast.walk(tree) if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef)
                      and node.body and isinstance(node.body[0], ast.Expr)}  # fmt: skip
        spelled += [f"{rel}:{n.lineno}: {n.value!r}" for n in ast.walk(tree)
                    if isinstance(n, ast.Constant) and n.value in kinds and n.value not in allowed and id(n) not in docstrings]  # fmt: skip
    assert not spelled, "a sensor kind spelled outside bots/sensor_kinds.py (iterate the registry): " + "; ".join(spelled)


DECLARING = {"sim/world/layout.py", "bots/odometry/layout.py", "bots/sensor_kinds.py", "bots/uncertainty.py"}
"""The modules that declare packed tables and the places along an axis (`ESTIMATE`, `ERROR`): an
offset's number is typed there, once; everyone else reads it by name."""


def test_no_integer_offset_is_typed_by_hand():
    """An index into an array is a name from a declaration (a table's field, `ESTIMATE.fused`),
    never a module constant bound to a number (`ENCODERS = 0`, `X, Y = range(2)`) outside the
    DECLARING modules: such a constant used as an index (a slice's bounds are lengths, not
    offsets) fails here with its file and line."""
    modules = {rel: tree for rel, tree in _trees()}
    offsets = {}  # (module name, constant) -> its file
    for rel, tree in modules.items():
        if rel in DECLARING:
            continue
        for node in tree.body:
            value = node.value if isinstance(node, ast.Assign) else None
            numbered = (isinstance(value, ast.Constant) and type(value.value) is int) or (
                isinstance(value, ast.Tuple) and value.elts and all(isinstance(e, ast.Constant) and type(e.value) is int for e in value.elts)) or (
                isinstance(value, ast.Call) and isinstance(value.func, ast.Name) and value.func.id == "range")  # fmt: skip
            if numbered:
                for target in node.targets:
                    for name in target.elts if isinstance(target, ast.Tuple) else [target]:
                        if isinstance(name, ast.Name) and name.id.isupper():
                            offsets[(rel[:-3].replace("/", "."), name.id)] = rel
    typed = []
    for rel, tree in modules.items():
        own = rel[:-3].replace("/", ".")
        names = {name: module for module, name in offsets if module == own}
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.module:
                names.update({a.asname or a.name: node.module for a in node.names if (node.module, a.name) in offsets})
        for node in ast.walk(tree):
            if isinstance(node, ast.Subscript):
                slices = {id(n) for s in ast.walk(node.slice) if isinstance(s, ast.Slice) for n in ast.walk(s)}
                typed += [f"{rel}:{node.lineno}: {n.id}" for n in ast.walk(node.slice) if isinstance(n, ast.Name) and n.id in names and id(n) not in slices]
    assert not typed, "an integer offset typed by hand outside the layouts (declare it in one, read it by name): " + "; ".join(typed)


NUMBERED = {"work": 0, "_work": 0, "tallies": 1}
"""The packed arrays still indexed by number, by the names they go by, and their axis of
declared places: the odometry's scratch workspace (`bots.odometry.layout.workspace`, planes by
`PLANE`) and a step's tallies (robots, counts by `bots.odometry.layout.TALLY`; the World's own
view of them is its TALLIES table)."""


def _plane_views(function: ast.AST) -> set[str]:
    """The names a function binds to one whole plane of its workspace (`rows = work[PLANE.x]`):
    their first index is a row declared in the layout, as the workspace's is a plane."""
    views = set()
    for node in ast.walk(function):
        if isinstance(node, ast.Assign):
            pairs = []
            for target in node.targets:
                if isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple):
                    pairs += zip(target.elts, node.value.elts)
                else:
                    pairs.append((target, node.value))
            views |= {t.id for t, v in pairs if isinstance(t, ast.Name) and isinstance(v, ast.Subscript) and NUMBERED.get(_name(v.value)) == 0
                      and not isinstance(v.slice, ast.Tuple | ast.Slice)}  # fmt: skip
    return views


def _name(node: ast.AST) -> str | None:
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else None


def test_no_literal_offset_into_a_numbered_array():
    """The odometry's workspace and a step's tallies are read by name: a plane by `PLANE`, a row
    of a plane by the layout's row names (`INCREMENT`, `UPDATE`), a count by `TALLY`, never by a
    number typed at the use (`work[5]`, `work[25:]`, `rows[6]`, `tallies[r, 0]`, `tallies[:, :2]`).
    Limits (where a number is not an offset into a table): the entries of a plane's matrices and
    vectors are numbered by their maths ((s, alpha), a 2 x 2 noise), the SCRATCH_PLANES
    temporaries (`scratch`, a slice of planes) by their place in one expression; only the names
    in NUMBERED are seen, and a view handed to another function under another name is not
    followed. The world's tables are structured arrays, read by field name
    (`test_no_integer_offset_is_typed_by_hand`)."""
    typed = []
    for rel, tree in _trees():
        for function in (n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)):
            axes = NUMBERED | dict.fromkeys(_plane_views(function), 0)
            for node in ast.walk(function):
                axis = axes.get(_name(node.value)) if isinstance(node, ast.Subscript) else None
                if axis is None:
                    continue
                index = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
                if axis < len(index):
                    place = index[axis]
                    bounds = [place.lower, place.upper] if isinstance(place, ast.Slice) else [place]
                    if any(isinstance(b, ast.Constant) and type(b.value) is int for b in bounds):
                        typed.append(f"{rel}:{node.lineno}: {ast.unparse(node)}")
    assert not typed, "a number typed as an offset into a numbered array (name it in bots/odometry/layout.py): " + "; ".join(sorted(set(typed)))
