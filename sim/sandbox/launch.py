"""The command that starts the guest: inside bubblewrap, or (asked for by name) degraded without it.

Inside bubblewrap the guest gets new user, mount, pid, network, IPC, UTS and cgroup namespaces (and
may make no user namespace of its own), no capabilities, its own session, and dies with its parent.
It is the first process of its pid namespace itself (no bubblewrap process beside it that it could
trace and make start processes for it). Its file system is built from nothing,
read-only: the interpreter, its standard library (its site-packages hidden) and the shared
libraries these and numpy load, each file at its own path (not /usr whole: no dist-packages, no
other programs); numpy; the guest's three files under /guest; the project modules asked for (with
what they import at module level) under /guest/lib; and the untrusted file (or its folder) under
/submission. Nothing else: no /etc, /home, /tmp, /proc (no mount table naming the teacher's
folders, no other process), the project's other code, the other submissions or the grader's
outputs; the only network is an unconfigured loopback.

Degraded, the guest is a plain child process with the same limits and filter but the file system
and network of the user running it: for a machine without bubblewrap, and only when asked for.
"""

from __future__ import annotations

import ast
import functools
import importlib.util
import os
import py_compile
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
"""The project's folder (holding sim/ and bots/)."""
PROJECT = ("sim", "bots")
GUEST_FILES = ("sim/sandbox/guest.py", "sim/sandbox/wire.py", "sim/sandbox/confine.py")
GUEST, LIB, SUBMISSION = "/guest", "/guest/lib", "/submission"
ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "LANG": "C.UTF-8", "HOME": SUBMISSION}
"""The guest's whole environment: one BLAS thread (each would reserve memory), nothing of the host's."""


def module_file(name: str) -> Path | None:
    """The file of the project module `name` (a package's __init__.py), or None."""
    base = ROOT.joinpath(*name.split("."))
    return next((p for p in (base / "__init__.py", base.with_suffix(".py")) if p.is_file()), None)


@functools.cache
def closure(modules: tuple[str, ...]) -> tuple[Path, ...]:
    """The project files `modules` need when imported: each one's file and, followed, the project
    modules it imports at module level (imports inside functions are not followed: they fail
    inside the sandbox only if called). Packages along the way stay namespaces unless imported by
    name, so that no package's `__init__` brings the rest of the project. Read once a process."""
    found: dict[str, Path] = {}
    todo = list(modules)
    while todo:
        name = todo.pop()
        path = module_file(name)
        if name in found or path is None:
            continue
        found[name] = path
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.Import):
                todo += [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                todo += [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        todo = [n for n in todo if n.split(".")[0] in PROJECT]
    return tuple(sorted(found.values()))


def bubblewrap() -> str | None:
    """The bwrap executable, or None."""
    return shutil.which("bwrap")


@functools.cache
def unavailable() -> str | None:
    """Why bubblewrap cannot isolate here (not installed, or namespaces refused), or None when it
    can; tried once per process by starting the interpreter in an empty sandbox."""
    executable = bubblewrap()
    if executable is None:
        return "bubblewrap (bwrap) is not installed"
    if shutil.which("ldd") is None:
        return "ldd is not installed (it lists the libraries the sandbox must hold)"
    command = [executable, *_namespaces(), *_system(), "--", _interpreter(), "-I", "-S", "-c", "pass"]
    try:
        result = subprocess.run(command, capture_output=True, timeout=60, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as err:
        return f"bubblewrap does not start ({err})"
    if result.returncode != 0:
        reason = result.stderr.decode(errors="replace").strip().splitlines()
        return f"bubblewrap cannot make a sandbox here: {reason[-1] if reason else f'exit {result.returncode}'}"
    return None


def _interpreter() -> str:
    return os.path.realpath(sys.executable)


def _namespaces() -> list[str]:
    return ["--unshare-all", "--unshare-user", "--disable-userns", "--uid", "65534", "--gid", "65534", "--cap-drop", "ALL",
            "--as-pid-1", "--die-with-parent", "--new-session", "--clearenv", "--dev", "/dev"]  # fmt: skip


def _system() -> list[str]:
    """The interpreter, its standard library (its site-packages hidden) and the shared libraries
    they and numpy load, read-only, each at its own path; nothing else of /usr or the installation."""
    args: list[str] = []
    for top in ("/bin", "/lib", "/lib64", "/sbin"):
        if os.path.islink(top):  # merged /usr: the loader's paths go through these links
            args += ["--symlink", os.readlink(top), top]
    for source, target in _system_files():
        args += ["--ro-bind", source, target]
    prefix = os.path.realpath(sys.base_prefix)
    paths = sysconfig.get_paths(vars={"base": prefix, "platbase": prefix})
    for hidden in sorted({paths["purelib"], paths["platlib"]}):
        if os.path.isdir(hidden):
            args += ["--tmpfs", hidden, "--remount-ro", hidden]
    return args


@functools.cache
def _system_files() -> tuple[tuple[str, str], ...]:
    """(host path, path inside) of the interpreter, its standard library folders and every shared
    library the interpreter, the standard library's extension modules and numpy's load (as `ldd`
    lists them). Found once a process."""
    prefix = os.path.realpath(sys.base_prefix)
    paths = sysconfig.get_paths(vars={"base": prefix, "platbase": prefix})
    folders = sorted({os.path.realpath(paths["stdlib"]), os.path.realpath(paths["platstdlib"])})
    numpy = Path(importlib.util.find_spec("numpy").origin).parent
    compiled = [str(p) for folder in folders for p in Path(folder, "lib-dynload").glob("*.so")]
    compiled += [str(p) for p in (*numpy.rglob("*.so"), *numpy.with_name("numpy.libs").glob("*.so*"))]
    files = [(_interpreter(), _interpreter())] + [(folder, folder) for folder in folders]
    libraries = [p for p in _libraries([_interpreter(), *compiled]) if not Path(p).resolve().is_relative_to(numpy.parent.resolve())]
    return tuple(files + [(library, _inside(library)) for library in libraries])  # numpy's own: under /guest/lib, found beside it


def _libraries(files: list[str]) -> list[str]:
    """The shared libraries `files` load, from `ldd` (absolute paths; not found ones left out)."""
    result = subprocess.run(["ldd", *files], capture_output=True, text=True, check=False, stdin=subprocess.DEVNULL)
    found = set()
    for line in result.stdout.splitlines():
        path = line.split("=>")[-1].strip().split(" (")[0]
        if path.startswith("/") and os.path.isfile(path):
            found.add(path)
    return sorted(found)


def _inside(path: str) -> str:
    """Where a library is bound inside: its folder resolved (the sandbox has the same /lib links),
    its own name kept (the name the loader asks for)."""
    return os.path.join(os.path.realpath(os.path.dirname(path)), os.path.basename(path))


def _numpy() -> list[tuple[str, str]]:
    """numpy's package folder and its bundled libraries, as (host path, path inside)."""
    package = Path(importlib.util.find_spec("numpy").origin).parent
    return [(str(p), f"{LIB}/{p.name}") for p in (package, package.with_name("numpy.libs")) if p.is_dir()]


def _with_compiled(source: Path, target: str) -> list[tuple[str, str]]:
    """`source` bound at `target`, and its compiled form beside it where Python looks for it (the
    guest writes nothing, so without it every start would compile the file again); compiled
    here first when missing or stale."""
    cache = Path(importlib.util.cache_from_source(str(source)))
    if not cache.is_file() or cache.stat().st_mtime < source.stat().st_mtime:
        py_compile.compile(str(source), str(cache), doraise=False)
    inside = importlib.util.cache_from_source(target)
    return [(str(source), target)] + ([(str(cache), inside)] if cache.is_file() else [])


def _start(path: list[str]) -> list[str]:
    """The interpreter's arguments that import the guest from `path` and serve (unbuffered: what
    the code printed reaches the excerpt even when it ends the process)."""
    return [_interpreter(), "-I", "-S", "-B", "-u", "-c", f"import sys; sys.path[:0] = {path!r}; import guest; guest.main()"]


def command(code: Path, folder: bool, modules: tuple[str, ...], config: dict, degraded: bool) -> list[str]:
    """The command line that starts the guest on `code` (bound with its whole folder if `folder`),
    with `modules` of the project importable; `config` completed with the paths inside."""
    config["preload"] = ["numpy", *modules]
    if degraded:
        site = str(Path(importlib.util.find_spec("numpy").origin).parents[1])
        config |= {"path": [str(ROOT / "sim" / "sandbox"), site, str(ROOT)], "code": str(code)}
        return [*_start(config["path"]), _json(config)]
    inside = f"{SUBMISSION}/{code.name}"
    binds = [(str(code.parent), SUBMISSION) if folder else (str(code), inside)] + _numpy()
    for name in GUEST_FILES:
        binds += _with_compiled(ROOT / name, f"{GUEST}/{Path(name).name}")
    for path in closure(modules):
        binds += _with_compiled(path, f"{LIB}/{path.relative_to(ROOT).as_posix()}")
    config |= {"path": [GUEST, LIB], "code": inside}
    args = [bubblewrap(), *_namespaces(), *_system()]
    for source, target in binds:
        args += ["--ro-bind", source, target]
    for key, value in ENVIRONMENT.items():
        args += ["--setenv", key, value]
    args += ["--remount-ro", "/dev", "--remount-ro", "/", "--chdir", SUBMISSION]
    return [*args, "--", *_start(config["path"]), _json(config)]


def _json(config: dict) -> str:
    import json

    return json.dumps(config, separators=(",", ":"))
