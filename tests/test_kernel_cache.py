"""numba's cache kept true to the modules kernels freeze (`sim.kernel_cache`): a constant changed in
a layout module alone recompiles the kernels of other files that use it, and the list of such
modules is complete."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

from sim.kernel_cache import ROOT, SHARED

KERNEL = """import numba

from pkg.layout import WIDTH


@numba.njit(cache=True)
def width():
    return WIDTH
"""
"""A kernel that freezes a constant of another file, as `bots/odometry/batch.py` freezes `ESTIMATE`."""
CALL = """import sys
from pathlib import Path

tree = Path(sys.argv[1])
sys.path.insert(0, str(tree))
if sys.argv[2] == "guarded":
    from sim.kernel_cache import keep_true

    print(keep_true(tree, ("pkg/layout.py",), ("pkg",)))
from pkg.kernel import width

print(width(), sum(width.stats.cache_hits.values()))
"""
"""A fresh process calling the kernel, after `keep_true` on the little tree where argv[2] says so;
prints what it dropped, the kernel's value and numba's cache hits."""


def _call(tree: Path, guarded: bool) -> list[str]:
    done = subprocess.run([sys.executable, "-c", CALL, str(tree), "guarded" if guarded else "bare"], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "PYTHONDONTWRITEBYTECODE": "1"}, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()


def test_a_constant_changed_in_a_layout_module_alone_recompiles_the_kernels_that_freeze_it(tmp_path: Path):
    """The kernel cached with WIDTH = 3 in a little tree; WIDTH set to 4 in its layout module alone:
    numba alone loads the stale kernel (3: its documented limit, which makes the check mean
    something); after `keep_true` the cache is dropped and the kernel compiled again (4), and the
    next process loads that from the cache (a hit)."""
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "layout.py").write_text("WIDTH = 3\n")
    (tmp_path / "pkg" / "kernel.py").write_text(KERNEL)
    assert _call(tmp_path, guarded=True) == ["True", "3", "0"]  # (no stamp yet: whatever is cached is dropped)
    assert _call(tmp_path, guarded=True) == ["False", "3", "1"]  # (stamped: loaded from the cache)
    (tmp_path / "pkg" / "layout.py").write_text("WIDTH = 4\n")
    assert _call(tmp_path, guarded=False) == ["3", "1"]  # numba alone: the stale kernel
    assert _call(tmp_path, guarded=True) == ["True", "4", "0"]  # dropped, compiled again
    assert _call(tmp_path, guarded=True) == ["False", "4", "1"]


def _module_file(module: str) -> str:
    path = ROOT / Path(*module.split("."))
    return (path / "__init__.py" if path.is_dir() else path.with_suffix(".py")).relative_to(ROOT).as_posix()


def _frozen_across_files() -> set[str]:
    """The modules of sim/ and bots/ whose names (constants, tables, kernels) a compiled function of
    another module uses inside its body: what numba compiles in and never checks again."""
    found = set()
    for path in sorted([*ROOT.glob("sim/**/*.py"), *ROOT.glob("bots/**/*.py")]):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        imported = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in ("sim", "bots"):
                for alias in node.names:
                    whole = f"{node.module}.{alias.name}"  # (a module imported by name: `from sim.world import layout`)
                    own = (ROOT / Path(*whole.split("."))).with_suffix(".py").exists()
                    imported[alias.asname or alias.name] = _module_file(whole if own else node.module)
            elif isinstance(node, ast.Import):
                imported |= {alias.asname: _module_file(alias.name) for alias in node.names if alias.asname and alias.name.split(".")[0] in ("sim", "bots")}
        here = path.relative_to(ROOT).as_posix()
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and any("jit" in ast.unparse(d) for d in node.decorator_list):
                found |= {imported[n.id] for n in ast.walk(node) if isinstance(n, ast.Name) and imported.get(n.id, here) != here}
    return found


def test_the_shared_modules_are_those_compiled_into_kernels_of_other_files():
    """`SHARED` is exactly the set of modules whose names compiled functions of other modules use:
    none missing (its change would leave stale kernels), none extra (its change would recompile
    every kernel for nothing)."""
    assert _frozen_across_files() == set(SHARED)
