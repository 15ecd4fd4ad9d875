"""The one base class of user mistakes, told apart from ctsim's own bugs.

A `UserError` is something the person running ctsim can fix (a world file, a robot file, an
option, a controller's name or parameters, a folder): the command line prints its message as one
line and exits 2. Every other exception is a bug in ctsim: the command line prints its traceback
and asks for a bug report (exit 1). A leaf module: it imports nothing, so any layer may raise it.
"""


class UserError(ValueError):
    """A mistake of the user's; `str()` is the whole message (naming the file and line, the option
    or the value). A ValueError, as the loaders' errors were before it existed."""
