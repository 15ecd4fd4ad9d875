"""numba's cache of compiled kernels kept true to the modules they freeze.

numba compiles a kernel's globals in as constants and invalidates its cache when the kernel's own
file changes, never for a change in another file (its documented limits, "Notes on Caching"). A
kernel cached before a constant of a layout module changed (`ESTIMATE`, `TALLY`, `PLANE` in
`bots/odometry/layout.py`, a table of `sim/world/layout.py`), or before a kernel it calls in
another file did, would go on running the old one. So the modules whose values or kernels are
compiled into kernels of other files (`SHARED`, a test holds the list complete) are fingerprinted
together, and where the fingerprint differs from the one stamped beside the caches, every cached
kernel of the tree is dropped (numba's documented way: remove its files; it tolerates missing
ones) and compiled again where next called. `sim` and `bots` check it when imported, before any of
their kernels can load from the cache.

Only the caches in the tree's `__pycache__` folders are watched (numba's place for them where the
tree is writable): an installed, read-only copy changes only when reinstalled, which rewrites every
file and so every kernel's own stamp; a `NUMBA_CACHE_DIR` elsewhere is not seen.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
"""The tree holding `sim` and `bots`."""
SHARED = (
    "bots/odometry/layout.py", "bots/uncertainty.py", "sim/world/layout.py", "sim/kinematics/arc.py",
    "sim/kinematics/batch.py", "bots/odometry/propagation.py", "bots/odometry/encoder.py", "bots/odometry/mouse.py", "bots/odometry/fused.py",
    "sim/world/kernels/floor.py", "sim/world/kernels/geometry.py", "sim/world/kernels/grids.py", "sim/world/kernels/pick.py",
    "sim/world/kernels/motion.py", "sim/world/kernels/sensing.py", "sim/world/kernels/contacts.py",
    "sim/world/kernels/light_pick.py", "sim/world/spec.py",
)  # fmt: skip
"""The modules (under ROOT) whose names kernels of other files use inside their compiled code:
the layouts' constants, and kernels called across files."""
STAMP = "kernel-sources.stamp"
"""The file in the first package's `__pycache__` holding the fingerprint the cached kernels were compiled with."""
PACKAGES = ("sim", "bots")
"""The folders whose `__pycache__` folders hold cached kernels."""


def fingerprint(root: Path, shared: Iterable[str]) -> str:
    """A digest of the `shared` files' names and contents (a missing one counts as empty)."""
    digest = hashlib.sha256()
    for name in shared:
        path = root / name
        digest.update(name.encode() + b"\0" + (path.read_bytes() if path.exists() else b"") + b"\0")
    return digest.hexdigest()


def keep_true(root: Path = ROOT, shared: Iterable[str] = SHARED, packages: tuple[str, ...] = PACKAGES) -> bool:
    """Drop every numba cache file under `packages`' `__pycache__` folders if the `shared` files
    changed since the stamp was written, then stamp them; True if it dropped them. A tree it may
    not write is left alone (see the module)."""
    stamp = root / packages[0] / "__pycache__" / STAMP
    try:
        found = fingerprint(root, shared)
        if stamp.exists() and stamp.read_text() == found:  # (no stamp yet: the caches there may be of any version)
            return False
        for package in packages:
            for cache in (root / package).rglob("__pycache__"):
                for compiled in (*cache.glob("*.nbi"), *cache.glob("*.nbc")):
                    compiled.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        written = stamp.with_name(f"{STAMP}.{os.getpid()}")
        written.write_text(found)
        written.replace(stamp)  # (whole or not at all, for processes starting side by side)
    except OSError:
        return False
    return True
