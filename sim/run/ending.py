"""How a run ends (`Ending`, the result's `reason`), and the exceptions that end it early or refuse
to start it."""

from __future__ import annotations

import signal
from enum import StrEnum

from sim.errors import UserError


class Ending(StrEnum):
    """How a run ended (`RunResult.reason`). A str: summary.json, tables and comparisons with the
    plain names ("goal") hold its value."""

    DURATION = "duration"
    """It ran for its whole duration."""
    GOAL = "goal"
    """A robot reached a goal area (with `until_goal`)."""
    DONE = "done"
    """Every robot's controller said it is done (its `status` is no longer RUNNING)."""
    QUIT = "quit"
    """The user closed the window (`ctsim play`)."""
    ERROR = "error"
    """A controller failed (raised, returned a bad command, overran its step time): `error` says how."""
    INTERRUPTED = "interrupted"
    """Ctrl-C (SIGINT)."""
    TERMINATED = "terminated"
    """SIGTERM (a job scheduler, `timeout`)."""
    JUDGED = "judged"
    """A referee (`run`'s `stop_when`, a contest's judge) ended the run; what it answered is the
    result's `verdict` (the judge's 'goal' or 'fall')."""

    @property
    def signalled(self) -> bool:
        """Whether a signal ended the run (Ctrl-C or SIGTERM): partial results, a status of its own;
        a contest's game or a sweep's run so cut short is no result and is run again."""
        return self in (Ending.INTERRUPTED, Ending.TERMINATED)

    @property
    def failed(self) -> bool:
        """Whether a controller failed (`RunResult.error` says how): exit status 1, a sweep's failed row."""
        return self is Ending.ERROR

    @property
    def reached_end(self) -> bool:
        """Whether the run came to its end on its own: its whole duration, or a goal; not a
        controller's, the user's, a referee's or a signal's doing (a firmware then gets the last
        step's reply, as from c't-Sim)."""
        return self in (Ending.DURATION, Ending.GOAL)


class RunError(UserError, RuntimeError):
    """A run that could not start (bad setup); the message is for the user."""


class Terminated(KeyboardInterrupt):
    """Raised by a SIGTERM handler (a job scheduler, `timeout`): the run ends as on Ctrl-C."""


def stopped_by(signum: int) -> KeyboardInterrupt:
    """What a stopping signal raises: Terminated for SIGTERM, KeyboardInterrupt for Ctrl-C."""
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


class Quit(KeyboardInterrupt):
    """Raised by an observer whose user ended the session (a window closed, Esc pressed): the run
    ends where it is, with reason 'quit'."""
