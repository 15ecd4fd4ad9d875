"""One writer per output folder: a command that writes a folder (run, sweep, contest, lab grade)
holds `LOCK` in it locked (flock) while it works, so that a second command into the same folder
is refused in one line instead of interleaving its files with the first's. The lock goes with
the process: a command that dies, however it dies, leaves the folder free."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from sim.errors import UserError

LOCK = ".ctsim.lock"
"""The lock file in a folder a command writes; it names the process and the command holding it."""


class FolderInUse(UserError):
    """Another ctsim command is writing the folder."""


def hold(folder: Path, command: str) -> IO[str] | None:
    """Create `folder` if need be and lock it for `command` (its name, as the refusal says it);
    the open lock file, whose closing frees the folder (None where files cannot be locked: not
    POSIX). FolderInUse when another process holds it."""
    try:
        import fcntl
    except ImportError:  # not POSIX: folders are not locked
        return None
    folder.mkdir(parents=True, exist_ok=True)
    handle = open(folder / LOCK, "a+", encoding="utf-8")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.seek(0)
        owner = handle.read(200).strip() or "unknown"
        handle.close()
        pid, _, theirs = owner.partition(" ")
        raise FolderInUse(f"{folder} is in use by another ctsim {theirs or 'command'} (process {pid}); "
                          "wait for it to end or give another --out") from None
    handle.truncate(0)
    handle.write(f"{os.getpid()} {command}\n")
    handle.flush()
    return handle


@contextmanager
def held(folder: Path, command: str) -> Iterator[None]:
    """`folder` locked for `command` while the block runs (`hold`)."""
    handle = hold(folder, command)
    try:
        yield
    finally:
        if handle is not None:
            handle.close()


def holder(folder: Path) -> str | None:
    """Who holds `folder` now ("process 4242, ctsim run"), or None when no command does."""
    try:
        import fcntl
    except ImportError:
        return None
    try:
        handle = open(folder / LOCK, encoding="utf-8")
    except OSError:
        return None
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            pid, _, command = handle.read(200).strip().partition(" ")
            return f"process {pid or 'unknown'}, ctsim {command or 'command'}"
        return None
