"""The layer rule of DESIGN.md §2: each layer imports only the layers before it, and no module
imports itself back through others (a circle). Every import counts, also those inside functions:
a lazy import hides a dependency from a reader but not from Python."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CORE = ("sim.kinematics",)
BOTS = CORE + ("bots",)
WORLD = CORE + ("sim.world", "bots.spec", "bots.ctbot", "bots.schema", "bots.readings", "bots.sensor_kinds", "bots.ir_curve")
RUN = WORLD + ("bots", "sim.run", "sim.guards")
ANALYSIS = RUN + ("sim.analysis",)
VIEWS = ANALYSIS + ("sim.views",)
SANDBOX = VIEWS + ("sim.sandbox",)  # DESIGN.md §2: untrusted code isolated; the lab and contests use it
CAPABILITIES = SANDBOX + ("sim.bridge", "sim.lab", "sim.experiments")

# (prefix of a module's name, the prefixes it may import), most specific first.
RULES = (
    ("sim.kinematics", CORE),
    ("bots", BOTS),
    ("sim.world", WORLD),
    ("sim.run", RUN),
    ("sim.guards", ()),
    ("sim.analysis", ANALYSIS),
    ("sim.views", VIEWS),
    ("sim.bridge", CAPABILITIES),
    ("sim.lab", CAPABILITIES),
    ("sim.experiments", CAPABILITIES),
    ("sim.web", CAPABILITIES + ("sim.web",)),
    ("sim.sandbox", SANDBOX),
    ("sim.contest", CAPABILITIES + ("sim.contest",)),
    ("sim.cli", ("sim", "bots")),
    ("sim.console", ("sim.cli",)),
    ("sim.errors", ()),
    ("sim.sanitize", ()),
    ("sim.folder_lock", ()),
    ("sim.out_files", ()),
    ("sim.interrupts", ()),
    ("sim.kernel_cache", ()),
)
# the bare package (its version and location) and six leaves any layer may use: the user-error
# base, the making safe of text from outside, the lock of an output folder and the writing of
# files into it without following links, Ctrl-C told apart from a KeyboardInterrupt code raises,
# and numba's cache kept true to the modules kernels freeze (which `import sim` does)
EVERYONE = ("sim", "sim.errors", "sim.sanitize", "sim.folder_lock", "sim.out_files", "sim.interrupts", "sim.kernel_cache")


def within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(root: Path, packages: tuple[str, ...] = ("sim", "bots")) -> dict[str, Path]:
    return {module_name(p, root): p for pkg in packages for p in sorted((root / pkg).rglob("*.py"))}


def imports(name: str, path: Path, known: dict[str, Path]) -> list[tuple[int, str]]:
    """(line, first-party module) for every import in the file; `from a import b` names a.b when
    b is a module."""
    is_package = path.name == "__init__.py"
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = name.split(".") if is_package else name.split(".")[:-1]
                package = package[: len(package) - node.level + 1]
                base = ".".join(package + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        found += [(node.lineno, t) for t in targets if t.split(".")[0] in ("sim", "bots")]
    return found


def layer_violations(root: Path) -> list[str]:
    known = modules(root)
    problems = []
    for name, path in known.items():
        allowed = next((allowed for prefix, allowed in RULES if within(name, prefix)), None)
        if allowed is None:
            if name != "sim":
                problems.append(f"{path.relative_to(root)}: module {name} belongs to no layer (DESIGN.md §2)")
            continue
        for line, target in imports(name, path, known):
            if target in EVERYONE or any(within(target, prefix) for prefix in allowed):
                continue
            problems.append(f"{path.relative_to(root)}:{line}: {name} imports {target}, a layer above it")
    return problems


def circles(root: Path) -> list[str]:
    """Import circles between modules (strongly connected components of the import graph)."""
    known = modules(root)
    graph = {name: {t for _, t in imports(name, path, known) if t in known and t != name} for name, path in known.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:  # Tarjan's algorithm
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while (w := stack.pop()) != v:
                component.append(w)
            if component:
                found.append(" <-> ".join(sorted(component + [v])))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_every_layer_imports_only_the_layers_before_it() -> None:
    problems = layer_violations(ROOT)
    assert not problems, "\n".join(problems)


def test_no_module_imports_itself_back_through_others() -> None:
    assert not circles(ROOT), "import circles:\n" + "\n".join(circles(ROOT))


def write(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")


@pytest.mark.parametrize(
    ("rel", "text", "expected"),
    [
        ("sim/kinematics/arc.py", "import numpy\nfrom sim.world import World\n", "sim/kinematics/arc.py:2: sim.kinematics.arc imports sim.world"),
        ("bots/odometry/base.py", "def f():\n    from sim.world.physics import World\n", "bots/odometry/base.py:2: bots.odometry.base imports sim.world.physics"),
        ("sim/views/figures.py", "from sim import cli\n", "sim/views/figures.py:1: sim.views.figures imports sim.cli"),
        ("sim/world/spec.py", "from ..run import run\n", "sim/world/spec.py:1: sim.world.spec imports sim.run"),
        ("sim/loose.py", "", "sim/loose.py: module sim.loose belongs to no layer"),
    ],
)
def test_the_rule_names_file_line_and_import_of_a_forbidden_import(tmp_path: Path, rel: str, text: str, expected: str) -> None:
    write(tmp_path, {"sim/__init__.py": "", "sim/cli.py": "", "sim/run.py": "", "sim/world/__init__.py": "",
                     "sim/world/physics.py": "", "sim/kinematics/__init__.py": "", "bots/__init__.py": "", rel: text})
    assert any(p.startswith(expected) for p in layer_violations(tmp_path)), layer_violations(tmp_path)


def test_a_circle_through_a_lazy_import_is_found(tmp_path: Path) -> None:
    write(tmp_path, {
        "sim/__init__.py": "", "bots/__init__.py": "",
        "bots/controller.py": "def make():\n    import bots.behaviours\n",
        "bots/behaviours/__init__.py": "from bots.behaviours.floor import X\n",
        "bots/behaviours/floor.py": "from bots.controller import make\nX = 1\n",
    })
    assert circles(tmp_path) == ["bots.behaviours <-> bots.behaviours.floor <-> bots.controller"]


def test_importing_a_controller_loads_no_physics() -> None:
    """Code on a robot sees readings only, and they are numpy arrays (`bots.readings`): importing a
    controller brings in no pymunk, numba or world."""
    code = "import sys, bots.controller; print(sorted(m for m in ('pymunk', 'numba', 'sim.world') if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]", done.stdout
