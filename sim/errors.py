"""The one base class of user mistakes, told apart from ctsim's own bugs.

A `UserError` is something the person running ctsim can fix (a world file, a robot file, an
option, a controller's name or parameters, a folder): the command line prints its message as one
line and exits with its `exit_status` (2; 1 for `UserCodeFailed`). Every other exception is a bug
in ctsim: the command line prints its traceback and asks for a bug report (exit 1). A leaf module: it imports nothing, so any layer may raise it.
"""


class UserError(ValueError):
    """A mistake of the user's; `str()` is the whole message (naming the file and line, the option
    or the value). A ValueError, as the loaders' errors were before it existed."""

    exit_status = 2
    """The command line's exit status: 2, a mistake found before anything ran."""


class UserCodeFailed(UserError):
    """The user's own code (a controller's or estimator's constructor) raised or called sys.exit
    before a run could start: one line naming what it did and where, exit 1 as for a run it
    failed (the user's code ran; their options were fine)."""

    exit_status = 1
