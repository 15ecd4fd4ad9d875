"""One writer per output folder: a command that writes a folder (run, sweep, contest, lab grade)
holds `LOCK` in it locked (flock) while it works, so that a second command into the same folder
is refused in one line instead of interleaving its files with the first's. The lock goes with
the process: a command that dies, however it dies, leaves the folder free (its lock file stays,
and the next command takes it over). A command that ends removes its lock file while it still
holds it, so that a finished folder holds only what the command wrote, and a lock file that
another process holds is never removed. The lock file is opened without following a link and
must be a regular file of its own (`sim.out_files`): a link, pipe, device or hard link planted in
its place is refused in one line, never truncated."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from sim.errors import UserError
from sim.out_files import NOFOLLOW, NotAFileOfItsOwn, kind
from sim.sanitize import name

LOCK = ".ctsim.lock"
"""The lock file in a folder a command writes; it names the process and the command holding it."""


class FolderInUse(UserError):
    """Another ctsim command is writing the folder."""


class Hold:
    """A folder held by this process (`hold`): `close` frees it."""

    def __init__(self, handle: IO[str], path: Path):
        self.handle, self.path = handle, path

    def close(self) -> None:
        """Remove the lock file while still holding it (no one else can hold it meanwhile, and
        one that is no longer the file held, replaced by hand, is left alone), then let go."""
        if self.handle.closed:
            return
        try:
            if _same(self.handle, self.path):
                os.unlink(self.path)
        except OSError:  # (a folder gone or made read-only meanwhile: the lock file stays, free)
            pass
        self.handle.close()


TRIES = 100
"""Times `hold` opens the lock file again when the one it locked was removed meanwhile (by a
holder ending between this open and this lock)."""


def hold(folder: Path, command: str) -> Hold | None:
    """Create `folder` if need be and lock it for `command` (its name, as the refusal says it);
    the hold, whose closing frees the folder (None where files cannot be locked: not POSIX).
    FolderInUse when another process holds it."""
    try:
        import fcntl
    except ImportError:  # not POSIX: folders are not locked
        return None
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK
    for _ in range(TRIES):
        handle = _open(path, os.O_RDWR | os.O_CREAT)
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            owner = name(handle.read(200).strip(), 200) or "unknown"  # (written by whoever holds it)
            handle.close()
            pid, _, theirs = owner.partition(" ")
            raise FolderInUse(f"{name(str(folder), 1000)} is in use by another ctsim {theirs or 'command'} (process {pid}); "
                              "wait for it to end or give another --out") from None
        if _same(handle, path):
            break
        handle.close()  # (its holder removed it as it ended: the folder is free, under a new lock file)
    else:
        raise FolderInUse(f"{name(str(folder), 1000)}: its lock file {LOCK} keeps being replaced; give another --out")
    handle.seek(0)
    handle.truncate(0)
    handle.write(f"{os.getpid()} {command}\n")
    handle.flush()
    return Hold(handle, path)


def _same(handle: IO[str], path: Path) -> bool:
    """Whether `path` is still the file `handle` has open."""
    try:
        there = os.lstat(path)
    except FileNotFoundError:
        return False
    here = os.fstat(handle.fileno())
    return (there.st_dev, there.st_ino) == (here.st_dev, here.st_ino)


@contextmanager
def held(folder: Path, command: str) -> Iterator[None]:
    """`folder` locked for `command` while the block runs (`hold`)."""
    taken = hold(folder, command)
    try:
        yield
    finally:
        if taken is not None:
            taken.close()


def holder(folder: Path) -> str | None:
    """Who holds `folder` now ("process 4242, ctsim run"), or None when no command does."""
    try:
        import fcntl
    except ImportError:
        return None
    try:
        handle = _open(folder / LOCK, os.O_RDONLY)
    except (OSError, NotAFileOfItsOwn):
        return None
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            pid, _, command = name(handle.read(200).strip(), 200).partition(" ")
            return f"process {pid or 'unknown'}, ctsim {command or 'command'}"
        return None


def _open(path: Path, flags: int) -> IO[str]:
    """The lock file, opened without following a link (NotAFileOfItsOwn for anything but a
    regular file with no other name)."""
    try:
        descriptor = os.open(path, flags | NOFOLLOW, 0o644)
    except OSError:
        if not os.path.lexists(path):
            raise
        info = os.lstat(path)  # (a link, a folder: not opened at all)
    else:
        info = os.fstat(descriptor)
        if stat.S_ISREG(info.st_mode) and info.st_nlink == 1:
            return os.fdopen(descriptor, "r+" if flags & os.O_RDWR else "r", encoding="utf-8", errors="replace")
        os.close(descriptor)
    what = kind(info.st_mode) if not stat.S_ISREG(info.st_mode) else f"a hard link (a file with {info.st_nlink} names)"
    raise NotAFileOfItsOwn(f"{name(str(path), 1000)} is {what}, not ctsim's lock file: ctsim locks and writes only a file of its own there (remove it)")
