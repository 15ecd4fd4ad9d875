"""Files ctsim writes into a folder, never through a link: whoever can put a symbolic link, a
hard link, a named pipe or a device into an output folder must not make ctsim write onto a file
outside it, block on it, or feed it.

A file is written under a fresh temporary name in its folder (created exclusively, so nothing
planted can stand there) and renamed onto its name at the end: the rename replaces whatever
stood at the name (a link itself, not its target; another name of the same file is left as it
was) and the file is whole or absent. A file rewritten in place (`open_in_place`) is opened
without following a link and used only when it is a regular file with no other name. A folder
ctsim creates inside its output (`subfolder`) must be a folder of its own, not a link to one.
What was written is tallied (`tallied`), so that a command that fails half-way names exactly the
files it wrote. Standard library only: a leaf any layer may use.
"""

from __future__ import annotations

import errno
import os
import resource
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from sim.errors import UserError
from sim.sanitize import name as shown

NOFOLLOW = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
"""Flags of every open of a file ctsim owns: not through a link, not blocking on a pipe."""


class NotAFileOfItsOwn(UserError):
    """A name ctsim writes in a folder stands for something it must not write through (a link to
    elsewhere, a folder, a pipe or a device)."""


def kind(mode: int) -> str:
    """What a file of this mode is, in words ("a named pipe")."""
    kinds = ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a named pipe"),
             (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    return next((name for test, name in kinds if test(mode)), "a regular file")


NEARLY_FULL = 64 << 20
"""Bytes left (on a disk, or under the file-size limit) below which a file that stopped taking
writes is said to have met that bound: a writer's chunk can be that large."""


def trouble(path: Path) -> str:
    """What the system says of a file that stopped taking writes through another program's writer
    (rerun's), which said why only on its own log: its folder gone, its disk (nearly) full, or
    the file-size limit (`ulimit -f`) (nearly) reached; '' when none of these."""
    folder = Path(path).parent
    if not folder.is_dir():
        return "its folder is gone"
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    try:
        size = os.lstat(path).st_size
    except OSError:
        size = 0
    if limit != resource.RLIM_INFINITY and limit - size < NEARLY_FULL:
        return f"{size / 1e6:.1f} MB written, and the file-size limit (ulimit -f) is {limit / 1e6:.1f} MB"
    try:
        disk = os.statvfs(folder)
    except OSError:
        return ""
    free = disk.f_bavail * disk.f_frsize
    return f"the disk holding it is full ({free / 1e6:.1f} MB free)" if free < NEARLY_FULL else ""


_TALLIES: list[list[Path]] = []
"""The tallies open now (`tallied`): each gets every file written."""


@contextmanager
def tallied() -> Iterator[list[Path]]:
    """A list that gets every file written while inside, in order, as it is renamed into its
    place or opened to be rewritten in place (a file written twice is in it twice): what a command
    says it wrote, also when it failed half-way, and nothing it did not."""
    tally: list[Path] = []
    _TALLIES.append(tally)
    try:
        yield tally
    finally:
        _TALLIES.remove(tally)


def _tally(path: Path) -> None:
    for tally in _TALLIES:
        tally.append(Path(path))


@contextmanager
def temporary_beside(path: Path) -> Iterator[Path]:
    """A fresh file name in `path`'s folder for a writer that opens files by name (pyarrow),
    renamed onto `path` when the block ends without an error (removed when it does not). Hidden
    and ending in .tmp: no reader of the folder's files by their extension takes it for one."""
    path = Path(path)
    temporary = path.with_name(f".{path.name[:100]}.{secrets.token_hex(6)}.tmp")
    os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | NOFOLLOW, 0o666))  # (the umask applies, as to any file)
    try:
        yield temporary
        _rename(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


@contextmanager
def replacing(path: Path, text: bool = False, newline: str | None = None) -> Iterator[IO]:
    """An open file whose content replaces `path` when the block ends without an error
    (`temporary_beside`); binary unless `text` (UTF-8)."""
    try:
        with temporary_beside(path) as temporary:
            descriptor = os.open(temporary, os.O_WRONLY | NOFOLLOW)
            with os.fdopen(descriptor, "w" if text else "wb", **({"encoding": "utf-8", "newline": newline} if text else {})) as file:
                yield file
    except OSError as err:
        if err.filename is None:  # (a write to a full disk names no file: the one it was for)
            err.filename = os.fspath(path)
        raise


def write_bytes(path: Path, data: bytes) -> Path:
    """`data` as the whole of `path` (`replacing`)."""
    with replacing(path) as file:
        file.write(data)
    return Path(path)


def write_text(path: Path, text: str) -> Path:
    """`text` as UTF-8, the whole of `path` (`replacing`)."""
    return write_bytes(path, text.encode("utf-8"))


def open_in_place(path: Path) -> IO[bytes] | None:
    """`path` opened for rewriting in place (r+b) when it is a regular file of its own (no link,
    no second name); None when it does not exist or is anything else (then write it anew)."""
    try:
        descriptor = os.open(path, os.O_RDWR | NOFOLLOW)
    except OSError:
        return None
    info = os.fstat(descriptor)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
        os.close(descriptor)
        return None
    _tally(path)
    return os.fdopen(descriptor, "r+b")


def own_file(path: Path) -> Path:
    """`path`, when nothing stands at it or a regular file of its own (no link, no second name)
    does, for a file a library opens by name to read and write in place (SQLite's database):
    NotAFileOfItsOwn otherwise."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return Path(path)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
        what = kind(info.st_mode) if not stat.S_ISREG(info.st_mode) else f"a hard link (a file with {info.st_nlink} names)"
        raise NotAFileOfItsOwn(f"{shown(str(path), 1000)} is {what}, not a file of its own: ctsim writes nothing through it (remove it)")
    return Path(path)


def subfolder(path: Path) -> Path:
    """`path` as a folder of its own (created if need be, with its parents): NotAFileOfItsOwn
    when it is a link or anything but a folder."""
    path = Path(path)
    if not os.path.lexists(path):
        path.mkdir(parents=True, exist_ok=True)
    mode = os.lstat(path).st_mode
    if not stat.S_ISDIR(mode):
        raise NotAFileOfItsOwn(f"{shown(str(path), 1000)} is {kind(mode)}, not a folder of its own: ctsim writes nothing through it (remove it or give another folder)")
    return path


def _rename(temporary: Path, path: Path) -> None:
    try:
        os.replace(temporary, path)
    except OSError as err:
        if err.errno in (errno.EISDIR, errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR):
            raise NotAFileOfItsOwn(f"{shown(str(path), 1000)} is a folder: ctsim cannot write its file there (remove it or give another folder)") from None
        raise
    _tally(path)
